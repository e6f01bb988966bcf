// Water on an oriented box: exact submerged volume, centre of buoyancy, wetted faces,
// and the buoyancy + drag load that follows from them. Pure, header-only, no Bullet.
//
// Geometry (submerged_box).  The box has half extents a = (a_x, a_y, a_z), centre x and
// orientation q (rotation R). The water occupies z <= z_w. The submerged part is the
// convex polyhedron P = box ∩ {z <= z_w}. It is built exactly:
//   1. each of the six faces (outward normal n_f = R e_k or -R e_k) is clipped against
//      the half space z <= z_w (Sutherland–Hodgman, one plane), giving the wetted face
//      polygons W_f (up to 5 vertices, orientation kept, so still outward);
//   2. the cut points on the plane close P with the cap C (the waterplane section, a
//      convex polygon, outward normal +z), sorted counter-clockwise about its mean.
// With a reference point p0 inside P (the mean of all polygon vertices) and every face
// fan-triangulated into (v0, v_i, v_i+1), the divergence theorem gives
//   V   = sum_t V_t,          V_t = det[v0 - p0, v_i - p0, v_i+1 - p0] / 6     (1)
//   c_B = sum_t V_t (p0 + v0 + v_i + v_i+1)/4  /  V                            (2)
// (signed tetrahedra; exact up to round-off for any pose). A_wp = area of C (3).
// Fully submerged and fully dry boxes take the short cut V = 8 a_x a_y a_z, c_B = x
// or V = 0.
//
// Load (box_water_load).  With rho_w the water density, g the gravity magnitude along -z:
//   buoyancy  F_b = rho_w g V e_z acting at c_B,  torque (c_B - x) x F_b            (4)
// Drag is a surface traction on the wetted faces W_f (cap excluded), with the local
// relative velocity u(r) = v + w x (r - x) - u_water and u_n = u . n_f:
//   linear    t_lin = -c_lin u_n n_f               on every wetted face           (5)
//   quadratic t_q   = -1/2 rho_w C_d u_n^2 n_f     on faces with u_n > 0 (leading) (6)
// The traction is integrated over each face by fan triangles with the three-edge-
// midpoint rule, which is exact for (5) (force and torque integrands are at most
// quadratic on a face) and for the force of (6) where u_n keeps its sign on a
// triangle. For a translating box (6) gives the classic 1/2 rho_w C_d A_proj |u| u.
// Tangential (skin) friction is neglected.
// Heave damping: a floating box heaving at speed w_z sees (5) on its bottom face only,
// i.e. a dashpot c_lin A_bottom; for a flat slab of thickness h and density rho_i the
// heave damping ratio is zeta = c_lin / (2 sqrt(rho_w g rho_i h)) (5a). Rotation is
// damped by the same traction since u varies over the face.
#pragma once

#include "common/types.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace hs::rigid {

/// A wetted (submerged) part of one box face: convex polygon, outward normal.
struct WettedFace {
  std::array<Vec3, 5> v{};  ///< vertices (world), counter-clockwise seen from outside
  int count = 0;            ///< 0 when the face is dry
  Vec3 normal = Vec3::Zero();
};

/// The submerged part of a box.
struct SubmergedBox {
  double volume = 0.0;                       ///< V, m^3 (1)
  Vec3 centre_of_buoyancy = Vec3::Zero();    ///< c_B, world, m (2); box centre when V = 0
  double waterplane_area = 0.0;              ///< A_wp, m^2 (3)
  std::array<WettedFace, 6> faces{};         ///< wetted faces W_f (cap excluded)

  /// Area (m^2) of the wetted face f.
  double face_area(int f) const {
    const WettedFace& w = faces[f];
    Vec3 s = Vec3::Zero();
    for (int i = 1; i + 1 < w.count; ++i) s += (w.v[i] - w.v[0]).cross(w.v[i + 1] - w.v[0]);
    return 0.5 * s.norm();
  }
  /// Projected area (m^2) of the submerged solid seen along the unit direction d:
  /// 1/2 sum over all faces of P (cap included) of |A_f n_f . d|.
  double projected_area(const Vec3& d) const {
    double s = std::abs(waterplane_area * d.z());
    for (int f = 0; f < 6; ++f) s += face_area(f) * std::abs(faces[f].normal.dot(d));
    return 0.5 * s;
  }
};

namespace detail {
// Clip a convex polygon against z <= zw; returns the new vertex count (<= n + 1).
inline int clip_below(const Vec3* in, int n, double zw, Vec3* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3& a = in[i];
    const Vec3& b = in[(i + 1) % n];
    const double da = a.z() - zw, db = b.z() - zw;
    if (da <= 0.0) out[m++] = a;
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
      const double t = da / (da - db);
      Vec3 p = a + t * (b - a);
      p.z() = zw;
      out[m++] = p;
    }
  }
  return m;
}
}  // namespace detail

/// Exact submerged part of the box (half extents `half`, centre `x`, orientation `q`)
/// below the water plane z = zw. See (1)–(3).
inline SubmergedBox submerged_box(const Vec3& half, const Vec3& x, const Quat& q, double zw) {
  SubmergedBox s;
  s.centre_of_buoyancy = x;
  const Mat3 R = q.toRotationMatrix();
  const Vec3 ex = R.col(0) * half.x(), ey = R.col(1) * half.y(), ez = R.col(2) * half.z();
  // Vertical reach of the box about its centre.
  const double reach = std::abs(ex.z()) + std::abs(ey.z()) + std::abs(ez.z());
  const bool dry = x.z() - reach >= zw;
  const bool wet = x.z() + reach <= zw;
  if (dry) return s;

  // Faces: +x, -x, +y, -y, +z, -z; vertices counter-clockwise seen from outside.
  const Vec3 axes[3] = {ex, ey, ez};
  for (int k = 0; k < 3; ++k) {
    const Vec3& n = axes[k];
    const Vec3& u = axes[(k + 1) % 3];
    const Vec3& w = axes[(k + 2) % 3];
    for (int sgn = 0; sgn < 2; ++sgn) {
      const int f = 2 * k + sgn;
      const double sg = sgn == 0 ? 1.0 : -1.0;
      const Vec3 c = x + sg * n;
      // (u, w, n) is right-handed, so c + u + w, c - u + w, ... is CCW about +n.
      Vec3 quad[4] = {c + u + w, c - u + w, c - u - w, c + u - w};
      if (sgn == 1) std::swap(quad[1], quad[3]);
      WettedFace& wf = s.faces[f];
      wf.normal = sg * R.col(k);
      if (wet) {
        for (int i = 0; i < 4; ++i) wf.v[i] = quad[i];
        wf.count = 4;
      } else {
        wf.count = detail::clip_below(quad, 4, zw, wf.v.data());
        if (wf.count < 3) wf.count = 0;
      }
    }
  }
  if (wet) {
    s.volume = 8.0 * half.x() * half.y() * half.z();
    return s;
  }

  // Cap: the cut points of the face polygons lie on z = zw; each appears twice (shared
  // edge), so deduplicate, then sort counter-clockwise about the mean (seen from +z).
  std::array<Vec3, 24> cap{};
  int nc = 0;
  const double tol = 1e-12 * (1.0 + half.maxCoeff());
  for (const WettedFace& wf : s.faces) {
    for (int i = 0; i < wf.count; ++i) {
      if (wf.v[i].z() != zw) continue;
      bool seen = false;
      for (int j = 0; j < nc && !seen; ++j) seen = (cap[j] - wf.v[i]).squaredNorm() <= tol * tol;
      if (!seen && nc < 24) cap[nc++] = wf.v[i];
    }
  }
  if (nc >= 3) {
    Vec3 m = Vec3::Zero();
    for (int i = 0; i < nc; ++i) m += cap[i];
    m /= nc;
    std::sort(cap.begin(), cap.begin() + nc, [&](const Vec3& a, const Vec3& b) {
      return std::atan2(a.y() - m.y(), a.x() - m.x()) < std::atan2(b.y() - m.y(), b.x() - m.x());
    });
    double a2 = 0.0;
    for (int i = 0; i < nc; ++i) {
      const Vec3& p = cap[i];
      const Vec3& r = cap[(i + 1) % nc];
      a2 += p.x() * r.y() - r.x() * p.y();
    }
    s.waterplane_area = 0.5 * std::abs(a2);
  } else {
    nc = 0;
  }

  // Reference point inside P: mean of the polygon vertices (limits cancellation).
  Vec3 p0 = Vec3::Zero();
  int np = 0;
  for (const WettedFace& wf : s.faces)
    for (int i = 0; i < wf.count; ++i) p0 += wf.v[i], ++np;
  if (np == 0) return s;
  p0 /= np;

  double vol = 0.0;
  Vec3 mom = Vec3::Zero();
  auto add_fan = [&](const Vec3* v, int n) {
    for (int i = 1; i + 1 < n; ++i) {
      const Vec3 a = v[0] - p0, b = v[i] - p0, c = v[i + 1] - p0;
      const double vt = a.dot(b.cross(c)) / 6.0;
      vol += vt;
      mom += vt * (p0 + 0.25 * (a + b + c));
    }
  };
  for (const WettedFace& wf : s.faces) add_fan(wf.v.data(), wf.count);
  add_fan(cap.data(), nc);
  if (vol > 0.0) {
    s.volume = vol;
    s.centre_of_buoyancy = mom / vol;
  }
  return s;
}

/// Water parameters for the box load (4)–(6).
struct BoxWaterParams {
  double level = 0.0;               ///< z_w, m
  double density = 1025.0;          ///< rho_w, kg/m^3
  double linear_drag = 0.0;         ///< c_lin, Pa s/m (= N s/m per m^2 of wetted face)
  double drag_coefficient = 0.0;    ///< C_d, quadratic pressure drag on leading faces
  Vec3 current = Vec3::Zero();      ///< u_water, m/s
};

/// Force and torque (about the box centre) of water on a box, N and N m.
struct WaterLoad {
  Vec3 force = Vec3::Zero();
  Vec3 torque = Vec3::Zero();
  double submerged_volume = 0.0;
};

/// Buoyancy (4) and drag (5)-(6) on a box with centre x, velocity v and angular
/// velocity w (world), for gravity magnitude g along -z.
inline WaterLoad box_water_load(const BoxWaterParams& p, double g, const Vec3& half, const Vec3& x,
                                const Quat& q, const Vec3& v, const Vec3& w) {
  WaterLoad load;
  const SubmergedBox s = submerged_box(half, x, q, p.level);
  if (s.volume <= 0.0) return load;
  load.submerged_volume = s.volume;
  const Vec3 fb(0.0, 0.0, p.density * g * s.volume);
  load.force += fb;
  load.torque += (s.centre_of_buoyancy - x).cross(fb);
  if (p.linear_drag <= 0.0 && p.drag_coefficient <= 0.0) return load;

  const double cq = 0.5 * p.density * p.drag_coefficient;
  for (const WettedFace& f : s.faces) {
    for (int i = 1; i + 1 < f.count; ++i) {
      const Vec3 t[3] = {f.v[0], f.v[i], f.v[i + 1]};
      const double area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
      if (area <= 0.0) continue;
      // Three edge midpoints, weight area/3 each.
      for (int k = 0; k < 3; ++k) {
        const Vec3 r = 0.5 * (t[k] + t[(k + 1) % 3]);
        const Vec3 u = v + w.cross(r - x) - p.current;
        const double un = u.dot(f.normal);
        double tn = -p.linear_drag * un;
        if (un > 0.0) tn -= cq * un * un;
        const Vec3 df = (tn * area / 3.0) * f.normal;
        load.force += df;
        load.torque += (r - x).cross(df);
      }
    }
  }
  return load;
}

}  // namespace hs::rigid

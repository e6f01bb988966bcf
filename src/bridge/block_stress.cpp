#include "block_stress.h"

#include "common/error.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace hs::bridge {

namespace {

bool positive_finite(double v) { return v > 0.0 && std::isfinite(v); }

}  // namespace

// ---- freeze bonds ----

FreezeBondEstimate freeze_bond_estimate(std::span<const FreezeJointSample> joints, const FreezeBondStrength& s) {
  if (!positive_finite(s.tensile))
    throw InputError("freeze_bond_strength", "tensile strength must be positive and finite (Pa), got " +
                                                 std::to_string(s.tensile));
  if (!positive_finite(s.shear))
    throw InputError("freeze_bond_shear_strength",
                     "shear strength must be positive and finite (Pa), got " + std::to_string(s.shear));
  FreezeBondEstimate e;
  for (std::size_t j = 0; j < joints.size(); ++j) {
    const FreezeJointSample& q = joints[j];
    if (!positive_finite(q.area))
      throw InputError("freeze_joint/area", "joint " + std::to_string(j) + ": bonded area must be positive (m^2), got " +
                                                std::to_string(q.area));
    if (!std::isfinite(q.tension) || !std::isfinite(q.shear))
      throw InputError("freeze_joint", "joint " + std::to_string(j) + ": load is not finite");
    // The ratio is formed as load / (A strength), the same product RigidWorld compares the load
    // with, so a joint loaded exactly at its breaking load gives u = 1 exactly.
    const double ut = std::max(q.tension, 0.0) / (q.area * s.tensile);
    const double us = std::abs(q.shear) / (q.area * s.shear);
    if (ut > e.utilisation) e = {ut, std::max(q.tension, 0.0) / q.area, j, FreezeBondMode::Tension};
    if (us > e.utilisation) e = {us, std::abs(q.shear) / q.area, j, FreezeBondMode::Shear};
  }
  return e;
}

// ---- flexure ----

namespace {

// A load in the block's frame (in a Beam: permuted so that x runs along it, (x, y, z) = (x_i, x_j, x_k)).
struct BeamLoad {
  Vec3 p, f;
};

// One beam: axis i, cross axes j = i+1, k = i+2 (cyclic, right-handed), everything in permuted
// coordinates. Holds the d'Alembert line loads and the section properties.
struct Beam {
  int i = 0, j = 1, k = 2;
  double a = 0, b = 0, c = 0;          // half extents along i, j, k
  double area = 0, s_j = 0, s_k = 0;   // A, section moduli about j and k
  Vec3 f = Vec3::Zero();               // F / (2a): uniform inertial line load (subtracted)
  double beta_y = 0, beta_z = 0;       // linear inertial line load slopes (see header)
  std::vector<BeamLoad> loads;         // sorted by x, descending

  Beam(int axis, const Vec3& he, const std::vector<BeamLoad>& local) {
    i = axis;
    j = (axis + 1) % 3;
    k = (axis + 2) % 3;
    a = he[i];
    b = he[j];
    c = he[k];
    area = 4.0 * b * c;
    s_j = 4.0 * b * c * c / 3.0;
    s_k = 4.0 * c * b * b / 3.0;
    loads.reserve(local.size());
    Vec3 F = Vec3::Zero(), Mc = Vec3::Zero();
    for (const BeamLoad& l : local) {
      const BeamLoad q{Vec3(l.p[i], l.p[j], l.p[k]), Vec3(l.f[i], l.f[j], l.f[k])};
      F += q.f;
      Mc += q.p.cross(q.f);
      loads.push_back(q);
    }
    std::stable_sort(loads.begin(), loads.end(), [](const BeamLoad& u, const BeamLoad& v) { return u.p.x() > v.p.x(); });
    // Rigid-box inertia per unit length mu = m/(2a): mu a_lin = F/(2a); mu alpha_y = M_c,y / (I_y/mu)
    // with I_y = m (a^2 + c^2)/3, i.e. 3 M_c,y / (2a (a^2 + c^2)); likewise about z with b.
    f = F / (2.0 * a);
    beta_y = 3.0 * Mc.y() / (2.0 * a * (a * a + c * c));
    beta_z = 3.0 * Mc.z() / (2.0 * a * (a * a + b * b));
  }
};

// Sums over the loads beyond a section (x > s): the external part of N and M is
//   N = Rx,  M_y = Qy + s Rz,  M_z = Qz - s Ry.
struct RightSums {
  double rx = 0, ry = 0, rz = 0, qy = 0, qz = 0;
  void add(const BeamLoad& l) {
    rx += l.f.x();
    ry += l.f.y();
    rz += l.f.z();
    qy += l.p.z() * l.f.x() - l.p.x() * l.f.z();
    qz += l.p.x() * l.f.y() - l.p.y() * l.f.x();
  }
};

struct Section {
  double n = 0, my = 0, mz = 0;
};

// Section forces at s of the loads in `r` plus the d'Alembert loads on (s, a]. With L = a - s the
// inertial contributions are (docs/bridge.md, derivation):
//   N  = -f_x L
//   M_y = -beta_y c^2/3 L + f_z L^2/2 - beta_y L^2 (2a + s)/6
//   M_z = -f_y L^2/2 - beta_z L^2 (2a + s)/6 - beta_z b^2/3 L
Section section_at(const Beam& bm, const RightSums& r, double s) {
  const double L = bm.a - s, L2 = L * L, cub = L2 * (2.0 * bm.a + s) / 6.0;
  Section q;
  q.n = r.rx - bm.f.x() * L;
  q.my = r.qy + s * r.rz - bm.beta_y * bm.c * bm.c / 3.0 * L + 0.5 * bm.f.z() * L2 - bm.beta_y * cub;
  q.mz = r.qz - s * r.ry - 0.5 * bm.f.y() * L2 - bm.beta_z * cub - bm.beta_z * bm.b * bm.b / 3.0 * L;
  return q;
}

double fibre_stress(const Beam& bm, const Section& q, bool axial) {
  return (axial ? q.n / bm.area : 0.0) + std::abs(q.my) / bm.s_j + std::abs(q.mz) / bm.s_k;
}

// Coefficients of N, M_y, M_z as polynomials c0 + c1 s + c2 s^2 + c3 s^3 on a segment with right
// sums r (the expansion of section_at; used only to find the stationary points).
struct Cubic {
  double c[4] = {0, 0, 0, 0};
};
void section_polynomials(const Beam& bm, const RightSums& r, Cubic& n, Cubic& my, Cubic& mz) {
  const double a = bm.a, a2 = a * a, a3 = a2 * a, by = bm.beta_y, bz = bm.beta_z;
  const double cc = bm.c * bm.c / 3.0, bb = bm.b * bm.b / 3.0;
  // L = a - s, L^2 = a^2 - 2as + s^2, L^2 (2a + s) = 2a^3 - 3a^2 s + s^3.
  n.c[0] = r.rx - bm.f.x() * a;
  n.c[1] = bm.f.x();
  my.c[0] = r.qy - by * cc * a + 0.5 * bm.f.z() * a2 - by * a3 / 3.0;
  my.c[1] = r.rz + by * cc - bm.f.z() * a + 0.5 * by * a2;
  my.c[2] = 0.5 * bm.f.z();
  my.c[3] = -by / 6.0;
  mz.c[0] = r.qz - 0.5 * bm.f.y() * a2 - bz * a3 / 3.0 - bz * bb * a;
  mz.c[1] = -r.ry + bm.f.y() * a + 0.5 * bz * a2 + bz * bb;
  mz.c[2] = -0.5 * bm.f.y();
  mz.c[3] = -bz / 6.0;
}

// Roots of d0 + d1 s + d2 s^2 inside (lo, hi), appended to out.
void roots_in(double d0, double d1, double d2, double lo, double hi, std::vector<double>& out) {
  auto keep = [&](double s) {
    if (std::isfinite(s) && s > lo && s < hi) out.push_back(s);
  };
  if (d2 == 0.0) {
    if (d1 != 0.0) keep(-d0 / d1);
    return;
  }
  const double disc = d1 * d1 - 4.0 * d2 * d0;
  if (disc < 0.0) return;
  // Numerically stable pair: q = -(d1 + sign(d1) sqrt(disc))/2, roots q/d2 and d0/q.
  const double q = -0.5 * (d1 + std::copysign(std::sqrt(disc), d1));
  if (q == 0.0) {
    keep(0.0);
    return;
  }
  keep(q / d2);
  keep(d0 / q);
}

void check_block(const BlockBox& block) {
  if (!block.half_extents.allFinite() || !(block.half_extents.minCoeff() > 0.0))
    throw InputError("block/half_extents", "half extents must be positive and finite (m)");
  if (!block.centre.allFinite()) throw InputError("block/centre", "centre must be finite");
  if (!block.orientation.coeffs().allFinite() || !(block.orientation.norm() > 1e-12))
    throw InputError("block/orientation", "orientation quaternion must be finite and non-zero");
}

// Loads in the block's frame, application points clamped into the box.
std::vector<BeamLoad> local_loads(const BlockBox& block, std::span<const PointLoad> loads) {
  const Mat3 Rt = block.orientation.normalized().toRotationMatrix().transpose();
  const Vec3& he = block.half_extents;
  std::vector<BeamLoad> out;
  out.reserve(loads.size());
  for (std::size_t n = 0; n < loads.size(); ++n) {
    if (!loads[n].point.allFinite() || !loads[n].force.allFinite())
      throw InputError("loads", "load " + std::to_string(n) + " is not finite");
    const Vec3 p = (Rt * (loads[n].point - block.centre)).cwiseMax(-he).cwiseMin(he);
    out.push_back({p, Rt * loads[n].force});
  }
  return out;
}

Vec3 unpermute(const Beam& bm, double my, double mz) {
  Vec3 m = Vec3::Zero();
  m[bm.j] = my;
  m[bm.k] = mz;
  return m;
}

}  // namespace

void flexure_beam_axes(const Vec3& he, int axes[2]) {
  std::array<int, 3> order{0, 1, 2};
  std::stable_sort(order.begin(), order.end(), [&](int u, int v) { return he[u] > he[v]; });
  axes[0] = order[0];
  axes[1] = order[1];
}

BeamSection beam_section(const BlockBox& block, std::span<const PointLoad> loads, int axis, double s,
                         const FlexureOptions& options) {
  check_block(block);
  if (axis < 0 || axis > 2) throw std::invalid_argument("beam_section: axis must be 0, 1 or 2");
  const double a = block.half_extents[axis];
  if (!(s >= -a && s <= a)) throw std::out_of_range("beam_section: s lies outside the block");
  const Beam bm(axis, block.half_extents, local_loads(block, loads));
  RightSums r;
  for (const BeamLoad& l : bm.loads)
    if (l.p.x() > s) r.add(l);
  const Section q = section_at(bm, r, s);
  return {q.n, unpermute(bm, q.my, q.mz), fibre_stress(bm, q, options.axial)};
}

FlexureEstimate flexure_estimate(const BlockBox& block, std::span<const PointLoad> loads, double flexural_strength,
                                 const FlexureOptions& options) {
  check_block(block);
  if (!positive_finite(flexural_strength))
    throw InputError("flexural_strength", "must be positive and finite (Pa), got " + std::to_string(flexural_strength));
  const std::vector<BeamLoad> local = local_loads(block, loads);
  FlexureEstimate best;
  if (local.empty()) return best;
  double best_sigma = -INFINITY;

  int axes[2];
  flexure_beam_axes(block.half_extents, axes);
  std::vector<double> cand;
  for (int axis : axes) {
    const Beam bm(axis, block.half_extents, local);
    // Segment ends: the load positions along the beam and its two ends, right to left.
    std::vector<double> xs{bm.a};
    for (const BeamLoad& l : bm.loads) xs.push_back(l.p.x());
    xs.push_back(-bm.a);
    xs.erase(std::unique(xs.begin(), xs.end()), xs.end());  // already sorted, descending
    RightSums r;
    std::size_t next = 0;  // loads[0, next) lie at x >= the current segment's right end
    for (std::size_t g = 0; g + 1 < xs.size(); ++g) {
      const double hi = xs[g], lo = xs[g + 1];
      while (next < bm.loads.size() && bm.loads[next].p.x() >= hi) r.add(bm.loads[next++]);
      // On (lo, hi) N, M_y, M_z are cubic in s. sigma = max over the signs (e_y, e_z) of
      // N/A + e_y M_y/S_j + e_z M_z/S_k; each signed sum is a cubic whose maximum on [lo, hi] is at
      // an end or a stationary point, so these candidates contain the maximum of sigma.
      Cubic n, my, mz;
      section_polynomials(bm, r, n, my, mz);
      cand.assign({hi, lo});
      const double wn = options.axial ? 1.0 / bm.area : 0.0;
      for (double ey : {1.0, -1.0})
        for (double ez : {1.0, -1.0}) {
          double t[4];
          for (int p = 0; p < 4; ++p) t[p] = wn * n.c[p] + ey * my.c[p] / bm.s_j + ez * mz.c[p] / bm.s_k;
          roots_in(t[1], 2.0 * t[2], 3.0 * t[3], lo, hi, cand);
        }
      std::sort(cand.begin(), cand.end());  // deterministic order: ties keep the smallest s
      for (double s : cand) {
        const Section q = section_at(bm, r, s);
        const double sigma = fibre_stress(bm, q, options.axial);
        if (sigma > best_sigma) {
          best_sigma = sigma;
          best.axis = axis;
          best.position = s;
          best.axial = q.n;
          best.moment_local = unpermute(bm, q.my, q.mz);
        }
      }
    }
  }
  best.stress = std::max(best_sigma, 0.0);
  best.utilisation = best.stress / flexural_strength;
  Vec3 e = Vec3::Zero();
  e[best.axis] = best.position;
  best.section_centre = block.centre + block.orientation.normalized() * e;
  return best;
}

// ---- conversion rule ----

bool converts(double utilisation, double safety_factor) {
  if (!positive_finite(safety_factor))
    throw InputError("conversion/safety_factor", "must be positive and finite, got " + std::to_string(safety_factor));
  return utilisation * safety_factor >= 1.0;
}

// ---- conversion region ----

void ConversionRegion::validate() const {
  if (!offset.allFinite()) throw InputError("conversion/region/offset", "must be finite (m)");
  if (shape == Shape::Box) {
    if (!half_extents.allFinite() || !(half_extents.minCoeff() > 0.0))
      throw InputError("conversion/region/half_extents", "box half extents must be positive and finite (m)");
  } else {
    if (!positive_finite(radius))
      throw InputError("conversion/region/radius", "cylinder radius must be positive and finite (m), got " +
                                                       std::to_string(radius));
    if (!std::isfinite(z_min) || !std::isfinite(z_max) || !(z_max > z_min))
      throw InputError("conversion/region/z_min", "cylinder z range must be finite with z_min < z_max, got [" +
                                                      std::to_string(z_min) + ", " + std::to_string(z_max) + "]");
  }
}

double ConversionRegion::distance(const Vec3& structure_position, const Vec3& p) const {
  const Vec3 d = p - (structure_position + offset);
  if (shape == Shape::Box) return (d.cwiseAbs() - half_extents).cwiseMax(0.0).norm();
  const double dr = std::max(std::hypot(d.x(), d.y()) - radius, 0.0);
  const double dz = std::max({z_min - d.z(), d.z() - z_max, 0.0});
  return std::hypot(dr, dz);
}

}  // namespace hs::bridge

// Box geometry of the generator: the separating-axis overlap of two oriented boxes and the
// volume of their intersection (freeze-joint patches, final overlap). See internal.h.
#include "ridge/internal.h"

namespace hs::rigid {

namespace detail {

/// SAT: minimum overlap depth over the 15 axes and that axis (from a to b); depth <= 0
/// means separated (the value is then the largest gap found, not a distance).
double sat(const Vec3& ha, const Vec3& xa, const Mat3& A, const Vec3& hb, const Vec3& xb,
           const Mat3& B, Vec3* axis) {
  const Vec3 d = xb - xa;
  double depth = std::numeric_limits<double>::infinity();
  Vec3 best = Vec3::UnitZ();
  auto test = [&](const Vec3& L) {
    const double o = reach(ha, A, L) + reach(hb, B, L) - std::abs(d.dot(L));
    if (o < depth) {
      depth = o;
      best = L;
    }
    return o > 0.0;
  };
  for (int i = 0; i < 3; ++i)
    if (!test(A.col(i))) return depth;
  for (int i = 0; i < 3; ++i)
    if (!test(B.col(i))) return depth;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      Vec3 c = A.col(i).cross(B.col(k));
      const double n = c.norm();
      if (n < 1e-6) continue;
      if (!test(c / n)) return depth;
    }
  if (axis) *axis = best.dot(d) < 0.0 ? Vec3(-best) : best;
  return depth;
}

namespace {

using Poly = std::vector<Vec3>;

/// Face polygons of a box, counter-clockwise about their outward normals.
std::array<Poly, 6> box_faces(const Vec3& h, const Vec3& x, const Mat3& R) {
  std::array<Poly, 6> faces;
  const Vec3 ax[3] = {R.col(0) * h.x(), R.col(1) * h.y(), R.col(2) * h.z()};
  for (int k = 0; k < 3; ++k) {
    const Vec3& n = ax[k];
    const Vec3& u = ax[(k + 1) % 3];
    const Vec3& w = ax[(k + 2) % 3];
    for (int sgn = 0; sgn < 2; ++sgn) {
      const Vec3 c = x + (sgn == 0 ? 1.0 : -1.0) * n;
      Poly q = {c + u + w, c - u + w, c - u - w, c + u - w};
      if (sgn == 1) std::swap(q[1], q[3]);
      faces[2 * k + sgn] = std::move(q);
    }
  }
  return faces;
}

/// Keeps the part of a convex polygon with n.p <= d.
Poly clip(const Poly& in, const Vec3& n, double d) {
  Poly out;
  const std::size_t m = in.size();
  for (std::size_t i = 0; i < m; ++i) {
    const Vec3& a = in[i];
    const Vec3& b = in[(i + 1) % m];
    const double da = n.dot(a) - d, db = n.dot(b) - d;
    if (da <= 0.0) out.push_back(a);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) out.push_back(a + (da / (da - db)) * (b - a));
  }
  return out;
}

}  // namespace

/// Volume and centroid of the intersection of two boxes: the faces of each box clipped to
/// the other box bound the (convex) intersection; divergence theorem with signed tetrahedra.
double box_intersection(const Vec3& ha, const Vec3& xa, const Mat3& A, const Vec3& hb,
                        const Vec3& xb, const Mat3& B, Vec3* centroid) {
  std::vector<Poly> polys;
  auto add = [&](const Vec3& h1, const Vec3& x1, const Mat3& R1, const Vec3& h2, const Vec3& x2,
                 const Mat3& R2) {
    for (Poly& f : box_faces(h1, x1, R1)) {
      Poly p = std::move(f);
      for (int k = 0; k < 3 && p.size() >= 3; ++k) {
        const Vec3 n = R2.col(k);
        p = clip(p, n, n.dot(x2) + h2[k]);
        if (p.size() >= 3) p = clip(p, -n, -n.dot(x2) + h2[k]);
      }
      if (p.size() >= 3) polys.push_back(std::move(p));
    }
  };
  add(ha, xa, A, hb, xb, B);
  add(hb, xb, B, ha, xa, A);
  Vec3 p0 = Vec3::Zero();
  std::size_t np = 0;
  for (const Poly& p : polys)
    for (const Vec3& v : p) p0 += v, ++np;
  if (np == 0) return 0.0;
  p0 /= static_cast<double>(np);
  double vol = 0.0;
  Vec3 mom = Vec3::Zero();
  for (const Poly& p : polys)
    for (std::size_t i = 1; i + 1 < p.size(); ++i) {
      const Vec3 a = p[0] - p0, b = p[i] - p0, c = p[i + 1] - p0;
      const double vt = a.dot(b.cross(c)) / 6.0;
      vol += vt;
      mom += vt * (p0 + 0.25 * (a + b + c));
    }
  if (centroid) *centroid = vol > 0.0 ? Vec3(mom / vol) : p0;
  return std::max(0.0, vol);
}

}  // namespace detail

double box_penetration(const Vec3& ha, const Vec3& xa, const Quat& qa, const Vec3& hb,
                       const Vec3& xb, const Quat& qb) {
  const double s = detail::sat(ha, xa, qa.toRotationMatrix(), hb, xb, qb.toRotationMatrix(), nullptr);
  return s > 0.0 ? s : 0.0;
}

}  // namespace hs::rigid

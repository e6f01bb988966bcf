#include "hcp_lattice.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace hs::bonded {

namespace {

// Generates lattice centres in the local frame over [xmin,xmax]x[ymin,ymax] and
// `layers` layers from z0, calling keep(p) to filter.
template <class Keep>
std::vector<Vec3> fill(double xmin, double xmax, double ymin, double ymax, double z0, int layers,
                       double D, const Pose& pose, Keep keep) {
  if (!(D > 0.0)) throw std::invalid_argument("HCP lattice: particle diameter must be positive");
  const double c = hcp_layer_spacing(D);
  const double row = D * std::sqrt(3.0) / 2.0;
  std::vector<Vec3> out;
  const Mat3 R = pose.orientation.normalized().toRotationMatrix();
  const int nrows = static_cast<int>(std::floor((ymax - ymin) / row)) + 2;
  const int ncols = static_cast<int>(std::floor((xmax - xmin) / D)) + 2;
  for (int k = 0; k < layers; ++k) {
    const bool b_layer = (k % 2) == 1;
    const double z = z0 + c * k;
    const double sx = b_layer ? 0.5 * D : 0.0;
    const double sy = b_layer ? row / 3.0 : 0.0;
    for (int j = -1; j < nrows; ++j) {  // from -1: shifted rows/layers may start earlier
      const double y = ymin + 0.5 * D + sy + row * j;
      const double xs = (j & 1) ? 0.5 * D : 0.0;
      for (int i = -1; i < ncols; ++i) {
        const double x = xmin + 0.5 * D + sx + xs + D * i;
        const Vec3 p(x, y, z);
        if (keep(p)) out.push_back(pose.position + R * p);
      }
    }
  }
  return out;
}

}  // namespace

std::vector<Vec3> hcp_fill_box(const Vec3& half, const Pose& pose, double D) {
  const double c = hcp_layer_spacing(D);
  const int layers = static_cast<int>(std::lround(2.0 * half.z() / c));
  const double eps = 1e-9 * D;
  return fill(-half.x(), half.x(), -half.y(), half.y(), -half.z() + 0.5 * c, layers, D, pose,
              [&](const Vec3& p) {
                return p.x() <= half.x() + eps && p.y() <= half.y() + eps &&
                       p.x() >= -half.x() - eps && p.y() >= -half.y() - eps;
              });
}

std::vector<Vec3> hcp_fill_prism(const std::vector<Eigen::Vector2d>& poly, double height,
                                 const Pose& pose, double D) {
  if (poly.size() < 3) throw std::invalid_argument("HCP prism: polygon needs at least 3 vertices");
  double xmin = poly[0].x(), xmax = xmin, ymin = poly[0].y(), ymax = ymin;
  for (const auto& p : poly) {
    xmin = std::min(xmin, p.x()); xmax = std::max(xmax, p.x());
    ymin = std::min(ymin, p.y()); ymax = std::max(ymax, p.y());
  }
  const double c = hcp_layer_spacing(D);
  const int layers = static_cast<int>(std::lround(height / c));
  auto inside = [&](const Vec3& p) {  // even-odd rule
    bool in = false;
    for (std::size_t a = 0, b = poly.size() - 1; a < poly.size(); b = a++) {
      const auto& pa = poly[a];
      const auto& pb = poly[b];
      if ((pa.y() > p.y()) != (pb.y() > p.y()) &&
          p.x() < (pb.x() - pa.x()) * (p.y() - pa.y()) / (pb.y() - pa.y()) + pa.x())
        in = !in;
    }
    return in;
  };
  return fill(xmin - D, xmax, ymin - D, ymax, 0.5 * c, layers, D, pose, inside);
}

std::size_t hcp_equalize_layers(std::vector<Vec3>& centres, const Pose& pose, double D) {
  const Mat3 R = pose.orientation.toRotationMatrix();
  const double c = hcp_layer_spacing(D);
  std::map<long, std::vector<Vec3>> layers;  // local coordinates, by layer (spacing c: keys 4 apart)
  for (const auto& p : centres) {
    const Vec3 l = R.transpose() * (p - pose.position);
    layers[std::lround(l.z() / c * 4.0)].push_back(l);
  }
  std::size_t n_min = centres.size();
  for (const auto& [k, v] : layers) n_min = std::min(n_min, v.size());
  const std::size_t removed = centres.size() - n_min * layers.size();
  centres.clear();
  // Within a layer two sites are >= D/2 apart in x, or share an x (a column: every other row)
  // and are >= sqrt(3) D apart in y. Compare with a tolerance of D/8, not the raw coordinates:
  // sites of one column differ in x only by the rounding of the rotation, and ordered by that noise the sort (so
  // which sites are trimmed, and the new particles' ids) would change with a 1e-16 change of the
  // pose, e.g. between a serial and an MPI run. (On such clustered values the tolerant order is
  // a strict weak order.)
  const double tol = 0.125 * D;
  for (auto& [k, v] : layers) {
    std::sort(v.begin(), v.end(), [tol](const Vec3& a, const Vec3& b) {
      if (a.x() < b.x() - tol) return true;
      if (b.x() < a.x() - tol) return false;
      return a.y() < b.y() - tol;
    });
    std::size_t lo = 0, hi = v.size();
    for (std::size_t q = 0; hi - lo > n_min; ++q) (q % 2 ? lo++ : hi--);
    for (std::size_t i = lo; i < hi; ++i) centres.push_back(pose.position + R * v[i]);
  }
  return removed;
}

}  // namespace hs::bonded

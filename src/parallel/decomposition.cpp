#include "decomposition.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace hs::par {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}

Decomposition::Decomposition(std::array<int, 3> dims) : dims_(dims) {
  for (int a = 0; a < 3; ++a) {
    if (dims_[a] < 1) throw std::invalid_argument("Decomposition: every grid dimension must be >= 1");
    cuts_[a].assign(dims_[a] + 1, 0.0);
    cuts_[a].front() = -kInf;
    cuts_[a].back() = kInf;
    for (int k = 1; k < dims_[a]; ++k) cuts_[a][k] = k;  // placeholder until set_uniform/balance
  }
}

std::array<int, 3> Decomposition::choose_dims(int n, const Vec3& extent) {
  std::array<int, 3> best{n, 1, 1};
  double best_cost = kInf;
  const Vec3 e = extent.cwiseMax(Vec3::Constant(1e-9));
  for (int px = n; px >= 1; --px) {  // descending: ties go to more cuts across x
    if (n % px) continue;
    for (int py = 1; py <= n / px; ++py) {
      if ((n / px) % py) continue;
      const int pz = n / px / py;
      // Internal cut area: (p_a - 1) planes perpendicular to axis a, each of the cross-section.
      const double cost = (px - 1) * e.y() * e.z() + (py - 1) * e.x() * e.z() + (pz - 1) * e.x() * e.y();
      if (cost < best_cost * (1.0 - 1e-9)) {
        best_cost = cost;
        best = {px, py, pz};
      }
    }
  }
  return best;
}

int Decomposition::rank_of(const Vec3& x) const {
  int c[3];
  for (int a = 0; a < 3; ++a) {
    const auto& cu = cuts_[a];
    // the last cut <= x among the interior ones
    const auto it = std::upper_bound(cu.begin() + 1, cu.end() - 1, x[a]);
    c[a] = static_cast<int>(it - (cu.begin() + 1));
  }
  return c[0] + dims_[0] * (c[1] + dims_[1] * c[2]);
}

std::array<int, 3> Decomposition::coords(int rank) const {
  return {rank % dims_[0], (rank / dims_[0]) % dims_[1], rank / (dims_[0] * dims_[1])};
}

Box Decomposition::box(int rank) const {
  const auto c = coords(rank);
  Box b;
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = cuts_[a][c[a]];
    b.hi[a] = cuts_[a][c[a] + 1];
  }
  return b;
}

void Decomposition::set_uniform(const Vec3& lo, const Vec3& hi) {
  for (int a = 0; a < 3; ++a)
    for (int k = 1; k < dims_[a]; ++k) cuts_[a][k] = lo[a] + (hi[a] - lo[a]) * k / dims_[a];
}

void Decomposition::balance(const std::array<std::vector<double>, 3>& hist, const Vec3& lo, const Vec3& hi) {
  for (int a = 0; a < 3; ++a) {
    if (dims_[a] == 1) continue;
    const auto& h = hist[a];
    const std::size_t nb = h.size();
    double total = 0.0;
    for (double w : h) total += w;
    if (!(total > 0.0) || nb == 0) {
      continue;
    }
    const double width = (hi[a] - lo[a]) / static_cast<double>(nb);
    double acc = 0.0;
    std::size_t b = 0;
    for (int k = 1; k < dims_[a]; ++k) {
      const double target = total * k / dims_[a];
      while (b < nb && acc + h[b] < target) acc += h[b++];
      // Interpolate inside bin b (uniform cost within a bin).
      const double frac = b < nb && h[b] > 0.0 ? (target - acc) / h[b] : 0.0;
      cuts_[a][k] = lo[a] + width * (static_cast<double>(b) + std::clamp(frac, 0.0, 1.0));
    }
    // Keep cuts strictly increasing (empty slabs are allowed but never inverted).
    for (int k = 2; k < dims_[a]; ++k) cuts_[a][k] = std::max(cuts_[a][k], cuts_[a][k - 1]);
  }
}

}  // namespace hs::par

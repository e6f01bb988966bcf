// Spatial decomposition of the DEM domain over MPI ranks: a rectilinear grid of px x py x pz
// boxes. Each axis has its own cut positions, shared by all boxes along it, so any point's owner
// is three binary searches and every rank knows every box. The outermost boxes extend to
// infinity: a particle can never leave the domain.
//
// Load balance: cuts are moved to equal-cost quantiles of the cost distribution along each axis
// (the marginal histogram of per-particle cost, summed over all ranks). With slabs (one axis cut)
// this balances exactly up to the histogram resolution; for a 3-D grid it balances each axis'
// slices, an approximation that is good when cost is roughly separable (docs/parallel.md).
#pragma once

#include "common/types.h"

#include <array>
#include <vector>

namespace hs::par {

struct Box {
  Vec3 lo, hi;
  bool contains(const Vec3& x) const {
    return x.x() >= lo.x() && x.x() < hi.x() && x.y() >= lo.y() && x.y() < hi.y() && x.z() >= lo.z() &&
           x.z() < hi.z();
  }
  /// Closed box grown by `h` on every side contains x.
  bool near(const Vec3& x, double h) const {
    return x.x() >= lo.x() - h && x.x() <= hi.x() + h && x.y() >= lo.y() - h && x.y() <= hi.y() + h &&
           x.z() >= lo.z() - h && x.z() <= hi.z() + h;
  }
  /// Some point of o lies within distance h (per axis) of this box.
  bool touches(const Box& o, double h) const {
    for (int a = 0; a < 3; ++a)
      if (lo[a] > o.hi[a] + h || o.lo[a] > hi[a] + h) return false;
    return true;
  }
};

class Decomposition {
 public:
  Decomposition() : Decomposition({1, 1, 1}) {}
  explicit Decomposition(std::array<int, 3> dims);

  /// The grid for n ranks over a domain of this extent: the factorisation px*py*pz = n with the
  /// least internal cut area (fewest ghosts), ties broken towards cutting x (the drift direction).
  static std::array<int, 3> choose_dims(int nranks, const Vec3& extent);

  const std::array<int, 3>& dims() const { return dims_; }
  int size() const { return dims_[0] * dims_[1] * dims_[2]; }
  int rank_of(const Vec3& x) const;
  Box box(int rank) const;
  std::array<int, 3> coords(int rank) const;
  /// Cut positions along an axis: dims[a] + 1 values, the outer two infinite.
  const std::vector<double>& cuts(int axis) const { return cuts_[axis]; }
  /// Replaces the cuts along `axis` (a checkpoint restore; same dims).
  void set_cuts(int axis, std::vector<double> c) { cuts_[axis] = std::move(c); }

  /// Uniform cuts over [lo, hi].
  void set_uniform(const Vec3& lo, const Vec3& hi);
  /// Cuts at the equal-cost quantiles of hist[a] (bins uniform over [lo[a], hi[a]]), per axis.
  void balance(const std::array<std::vector<double>, 3>& hist, const Vec3& lo, const Vec3& hi);

 private:
  std::array<int, 3> dims_;
  std::array<std::vector<double>, 3> cuts_;
};

}  // namespace hs::par

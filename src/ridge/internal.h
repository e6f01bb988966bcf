// Private to hs_ridge (src/ridge): what the generator's phases share. The random stream and box
// geometry, the spatial hash, a placed block, the run's state, and the phases that
// generate_ridge (generate.cpp) runs in order: the ice sheet and placement (placement.cpp),
// compaction and settling (settle.cpp), freeze joints and measurement (measure.cpp).
#pragma once

#include "ridge/ridge.h"
#include "rigid/rigid_world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <unordered_map>
#include <vector>

namespace hs::rigid::detail {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr double kTwoPi = 2.0 * 3.14159265358979323846;

// ---------------------------------------------------------------- random numbers
// mt19937_64 is specified bit for bit by the standard; the distributions are not, so they
// are written out here (same seed -> same ridge with any standard library).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  double uniform() { return static_cast<double>(g_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  double normal() {  // Box-Muller, both values used
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(kTwoPi * u2);
    has_spare_ = true;
    return r * std::cos(kTwoPi * u2);
  }
  Quat rotation() {  // uniform on SO(3) (Shoemake)
    const double u1 = uniform(), u2 = uniform(), u3 = uniform();
    const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
    return Quat(b * std::cos(kTwoPi * u3), a * std::sin(kTwoPi * u2), a * std::cos(kTwoPi * u2),
                b * std::sin(kTwoPi * u3));
  }

 private:
  std::mt19937_64 g_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

inline double sample_ln_r(Rng& rng, double m, double s) {
  for (;;) {
    const double z = rng.normal();
    if (std::abs(z) <= 4.0) return m + s * z;
  }
}

// ---------------------------------------------------------------- box geometry
/// Half extent of the box along the unit direction e.
inline double reach(const Vec3& h, const Mat3& R, const Vec3& e) {
  return h.x() * std::abs(R.col(0).dot(e)) + h.y() * std::abs(R.col(1).dot(e)) +
         h.z() * std::abs(R.col(2).dot(e));
}
/// Half extents of the box's axis-aligned bounding box.
inline Vec3 aabb_half(const Vec3& h, const Mat3& R) {
  return Vec3(reach(h, R, Vec3::UnitX()), reach(h, R, Vec3::UnitY()), reach(h, R, Vec3::UnitZ()));
}

/// SAT: minimum overlap depth over the 15 axes and that axis (from a to b); depth <= 0
/// means separated (the value is then the largest gap found, not a distance).
double sat(const Vec3& ha, const Vec3& xa, const Mat3& A, const Vec3& hb, const Vec3& xb,
           const Mat3& B, Vec3* axis);
/// Volume and centroid of the intersection of two boxes (geometry.cpp).
double box_intersection(const Vec3& ha, const Vec3& xa, const Mat3& A, const Vec3& hb,
                        const Vec3& xb, const Mat3& B, Vec3* centroid);

// ---------------------------------------------------------------- spatial hash
class HashGrid {
 public:
  explicit HashGrid(double cell) : cell_(cell) {}
  void insert(std::int32_t id, const Vec3& lo, const Vec3& hi) {
    for_cells(lo, hi, [&](std::uint64_t k) { map_[k].push_back(id); });
  }
  /// Ids whose boxes were inserted over cells touching [lo, hi], each once, ascending.
  void query(const Vec3& lo, const Vec3& hi, std::vector<std::int32_t>& out) {
    out.clear();
    for_cells(lo, hi, [&](std::uint64_t k) {
      auto it = map_.find(k);
      if (it == map_.end()) return;
      for (std::int32_t id : it->second) {
        if (static_cast<std::size_t>(id) >= stamp_.size()) stamp_.resize(id + 1, 0);
        if (stamp_[id] == epoch_) continue;
        stamp_[id] = epoch_;
        out.push_back(id);
      }
    });
    ++epoch_;
    std::sort(out.begin(), out.end());
  }
  const std::vector<std::int32_t>* cell_of(const Vec3& p) const {
    auto it = map_.find(key(idx(p.x()), idx(p.y()), idx(p.z())));
    return it == map_.end() ? nullptr : &it->second;
  }

 private:
  std::int64_t idx(double v) const { return static_cast<std::int64_t>(std::floor(v / cell_)); }
  static std::uint64_t key(std::int64_t i, std::int64_t j, std::int64_t k) {
    const std::uint64_t o = 1u << 20, m = (1u << 21) - 1;
    return ((static_cast<std::uint64_t>(i + o) & m) << 42) |
           ((static_cast<std::uint64_t>(j + o) & m) << 21) | (static_cast<std::uint64_t>(k + o) & m);
  }
  template <class F>
  void for_cells(const Vec3& lo, const Vec3& hi, F&& f) {
    const std::int64_t i0 = idx(lo.x()), i1 = idx(hi.x()), j0 = idx(lo.y()), j1 = idx(hi.y()),
                       k0 = idx(lo.z()), k1 = idx(hi.z());
    for (std::int64_t i = i0; i <= i1; ++i)
      for (std::int64_t j = j0; j <= j1; ++j)
        for (std::int64_t k = k0; k <= k1; ++k) f(key(i, j, k));
  }
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<std::int32_t>> map_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t epoch_ = 1;
};

struct Placed {
  Vec3 h, x;
  Quat q;
  Mat3 R;
  Vec3 aabb;
  int part;
};

/// State shared by the phases: the definition, the random stream, the progress callback.
struct RidgeRun {
  const RidgeDef& d;
  const RidgeProgressFn& progress;
  Rng rng;
  double lnm = 0.0, lns = 0.0;  ///< log-normal parameters of the aspect ratio
  double kx = 0.0, sx = 0.0;    ///< keel and sail half widths, m
  double ice_half = 0.0;        ///< half width of the ice sheet, m
  double wcl = 0.0;             ///< width of the consolidated layer within it, m

  RidgeRun(const RidgeDef& def, const RidgeProgressFn& p) : d(def), progress(p), rng(def.seed) {
    d.aspect.log_params(lnm, lns);
  }
  void report(const char* phase, double t, double ke, std::size_t n, double disp = -1.0) const {
    if (!progress) return;
    RidgeProgress q;
    q.phase = phase;
    q.max_displacement = disp;
    q.time = t;
    q.max_time = d.settle.max_time;
    q.kinetic_energy_per_block = ke;
    q.blocks = n;
    progress(q);
  }
};

/// The ice sheet into `ice` (fixed boxes or floating plates); sets run's widths (placement.cpp).
void add_ice_sheet(RidgeRun& run, std::vector<IceBox>& ice);
/// Blocks placed into the target envelopes, keel then sail; their target and block volumes
/// go to `st` (placement.cpp).
std::vector<Placed> place_blocks(RidgeRun& run, RidgeStats& st);
/// The rigid world's settings while settling (settle.cpp; resettle_ridge starts from them).
RigidWorldDef settle_world_def(const RidgeDef& d);
/// Compaction and settling of `placed` in the rigid world under res.ice; the settled blocks
/// go to res.blocks and back into `placed`, the plates' poses and the settle figures to res
/// (settle.cpp). Returns the last mean kinetic energy per block, J.
double settle_blocks(const RidgeRun& run, std::vector<Placed>& placed, RidgeResult& res);
/// Freeze joints, the achieved profile and the porosity of the settled blocks (measure.cpp).
void join_and_measure(const RidgeRun& run, const std::vector<Placed>& placed, double ke, RidgeResult& res);

}  // namespace hs::rigid::detail

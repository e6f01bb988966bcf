// Particle store: structure of arrays, one array per field.
//
// Index ranges (the one rule every loop follows):
//   [0, n_owned)                 owned particles: integrated by this rank
//   [n_owned, n_owned + n_ghost) ghosts: read-only copies of neighbours' particles
// Forces are only ever integrated for owned particles; pair loops may write
// forces into ghosts, which are discarded (or reverse-communicated) later.
//
// Every particle has a stable 64-bit global id; bonds and contact history refer
// to particles by global id, so they survive reordering (spatial sort) and can
// travel with their particles between ranks.
#pragma once

#include "common/types.h"

#include <algorithm>
#include <cassert>
#include <unordered_map>
#include <vector>

namespace hs::bonded {

/// Per-particle material tag: index into the engine's material table.
using MaterialIndex = std::uint16_t;

/// Flags on a particle.
enum ParticleFlag : std::uint8_t {
  kFlagNone = 0,
  kFlagFrozen = 1,  ///< not integrated (held in place, e.g. a clamp in a test)
};

struct ParticleInit {
  Vec3 x = Vec3::Zero();
  Vec3 v = Vec3::Zero();
  Vec3 omega = Vec3::Zero();
  Quat q = Quat::Identity();
  double radius = 0.25;       ///< contact radius, m
  double mass = 0.0;          ///< kg
  double buoyant_volume = 0;  ///< m^3 of water displaced when fully submerged
  MaterialIndex material = 0;
  std::uint8_t flags = kFlagNone;
};

/// Everything a particle carries, packed for migration and ghost copies between ranks.
struct ParticleRecord {
  Vec3 x, v, omega;
  Quat q;
  double radius, inv_mass, inv_inertia, mass, buoyant_volume;
  GlobalId gid;
  MaterialIndex material;
  std::uint8_t flags, bond_count;
};

/// Reorders the first order.size() elements of a in place: new a[k] = old a[order[k]] (order a
/// permutation of 0..order.size()-1; the elements after them stay). The permutation's cycles are
/// followed with one element in hand, so no second array is made: a rebuild's sort touches no
/// fresh pages (after a rebuild most particles stay where they were, and are skipped). `done` is
/// scratch (one flag per element). An order that is not a permutation would not end: the callers
/// make theirs by a counting sort of every owned particle, or of the bonds.
template <class T>
void permute_in_place(std::vector<T>& a, const std::vector<std::uint32_t>& order, std::vector<char>& done) {
  const std::size_t n = order.size();
  assert(a.size() >= n);
  done.assign(n, 0);
  for (std::size_t s = 0; s < n; ++s) {
    if (done[s] || order[s] == s) continue;
    const T held = a[s];
    std::size_t k = s;
    for (;;) {
      done[k] = 1;
      const std::size_t from = order[k];
      if (from == s) {
        a[k] = held;
        break;
      }
      a[k] = a[from];  // (a[from] not yet written: the cycle reaches it next)
      k = from;
    }
  }
}

class ParticleStore {
 public:
  // ---- hot state, touched every step ----
  std::vector<Vec3> x;       ///< position, m
  std::vector<Vec3> v;       ///< velocity, m/s
  std::vector<Vec3> f;       ///< force accumulator, N
  std::vector<Vec3> omega;   ///< angular velocity (world frame), rad/s
  std::vector<Vec3> torque;  ///< torque accumulator (world frame), N m
  std::vector<Quat> q;       ///< orientation, body -> world
  std::vector<double> radius;   ///< m
  std::vector<double> inv_mass; ///< 1/kg (0 = immovable)
  std::vector<double> inv_inertia;  ///< 1/(kg m^2), spheres: isotropic
  // ---- cold state / bookkeeping ----
  std::vector<double> mass;            ///< kg
  std::vector<double> buoyant_volume;  ///< m^3
  std::vector<GlobalId> gid;
  std::vector<MaterialIndex> material;
  std::vector<std::uint8_t> flags;
  std::vector<std::uint8_t> bond_count;  ///< intact bonds on this particle

  std::size_t n_owned = 0;
  std::size_t n_ghost = 0;

  std::size_t size() const { return x.size(); }
  std::size_t owned() const { return n_owned; }

  /// Append an owned particle (only valid while there are no ghosts). Returns its index.
  std::size_t add(const ParticleInit& p, GlobalId id);
  /// Next unused global id (ids are never reused).
  GlobalId next_gid() const { return next_gid_; }
  GlobalId add_auto(const ParticleInit& p) { return gid[add(p, next_gid_)]; }
  /// Moves the counter on to at least `next` (under MPI every rank keeps the same counter:
  /// ids handed out on one rank are skipped on the others).
  void advance_gid(GlobalId next) { next_gid_ = std::max(next_gid_, next); }

  ParticleRecord record(std::size_t i) const;
  /// Appends a particle at the end of the arrays (the caller keeps n_owned / n_ghost right).
  void push(const ParticleRecord& r);
  /// Keeps the first n particles (drops ghosts when n == n_owned).
  void truncate(std::size_t n);

  /// Reorder owned particles by `order` (new index k takes old index order[k]).
  void permute(const std::vector<std::uint32_t>& order);
  /// Remove owned particles whose `keep` flag is false; preserves relative order.
  void compact(const std::vector<char>& keep);

  /// Global id -> local index (rebuilt by rebuild_index()).
  std::uint32_t local(GlobalId id) const {
    auto it = index_.find(id);
    return it == index_.end() ? kNone : it->second;
  }
  void rebuild_index();
  static constexpr std::uint32_t kNone = 0xffffffffu;

  void clear_forces();
  void reserve(std::size_t n);

 private:
  GlobalId next_gid_ = 0;
  std::unordered_map<GlobalId, std::uint32_t> index_;
};

}  // namespace hs::bonded

// Particle -> block coupling under MPI (docs/parallel.md, "Rigid blocks under MPI").
//
// Every rank keeps a full, replicated copy of the rigid world (thousands of blocks: cheap) and
// steps it identically. Particle forces on a block are found by whichever rank owns the particle,
// so each rank holds only part of every block's load. At each rigid step the accumulated linear
// and angular impulses are summed over the ranks (reduced on rank 0, then broadcast, so every
// rank receives the same bits) and applied to every copy, in block order: the copies stay
// bit-identical, and a later conversion of a block happens identically on every rank.
#pragma once

#include "parallel/comm.h"
#include "rigid/rigid_world.h"

#include <vector>

namespace hs::bridge {

class ImpulseCoupler {
 public:
  /// Clears and sizes the accumulators for `blocks` (the world's blocks, in a fixed order).
  void reset(const std::vector<rigid::BlockId>& blocks);
  /// Adds an impulse j (N s) at the world point p on block k (index into the reset() list).
  void add(std::size_t k, const Vec3& j, const Vec3& p, const Vec3& block_centre);
  /// Adds an impulse j (N s) through block k's centre and an angular impulse h (N m s) about it,
  /// e.g. what BlockContact accumulated on this rank (block_contact.h).
  void add_about_centre(std::size_t k, const Vec3& j, const Vec3& h);
  /// Sums the accumulators over the ranks (collective) and applies them to `world`, then clears.
  /// Returns the number of blocks that received an impulse.
  std::size_t sum_and_apply(const par::Comm& comm, rigid::RigidWorld& world);

  const std::vector<Vec3>& linear() const { return linear_; }
  const std::vector<Vec3>& angular() const { return angular_; }

 private:
  std::vector<rigid::BlockId> blocks_;
  std::vector<Vec3> linear_, angular_;  ///< N s and N m s about each block's centre
};

}  // namespace hs::bridge

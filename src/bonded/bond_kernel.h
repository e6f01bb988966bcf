// The bond kernel: every parallel bond's force and moment in one pass, several bonds at a time.
//
// Engine::bonds_ (std::vector<Bond>) stays the authority on bonds: their particles (local index and
// global id), kind and reference state (BondRef: lever arms ri, rj in the body frames, relative
// orientation c). BondBatch is a structure-of-arrays copy of it for the kernel, in the same order,
// remade from bonds_ at every neighbour rebuild and edited like it after breaks (erase): nothing in
// it is state of its own. The law is the one of bond_parallel.h (parallel_bond); the kernel evaluates
// its formulas for kLanes bonds at once in SIMD registers (GCC vector extensions: 8 lanes in AVX-512
// zmm or 4 in AVX2 ymm with -march=native, two SSE2 halves in a portable build; each lane's
// operations are the same at any width, so the width does not change results).
//
// Results do not depend on where a bond sits in the batch, nor on the rank count: every lane runs
// the same instructions, the padding lanes of the last batch repeat a real bond and are dropped,
// and a bond whose rotation is too large for the series (rotation vector beyond 0.02 rad, log-map
// Jacobian beyond 0.0316 rad: ice bonds break long before) is recomputed by the scalar
// parallel_bond, chosen by its own data only. Forces are added to the particles in bond order, as
// the scalar loop did.
#pragma once

#include "bond_parallel.h"
#include "common/types.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hs::bonded {

struct Bond;
struct BrokenBond;

/// Structure-of-arrays copy of the bonds (see above). Arrays are padded to a multiple of kLanes.
class BondBatch {
 public:
#ifdef HS_BOND_LANES
  static constexpr std::size_t kLanes = HS_BOND_LANES;
#elif defined(__AVX512F__)
  static constexpr std::size_t kLanes = 8;
#else
  static constexpr std::size_t kLanes = 4;
#endif

  /// Copies `bonds` (in order); kinds index `params` of bond_kernel.
  void pack(const std::vector<Bond>& bonds);
  /// Removes the bonds `gone` (ascending indices into the copy, as bond_kernel reports them),
  /// keeping the others' order: the copy of a bond list from which the same bonds were erased.
  void erase(const std::vector<BrokenBond>& gone);
  /// Marks the copy stale (bonds_ reordered or edited): the next bond_forces() repacks it.
  void invalidate() { valid_ = false; }
  /// True when the copy is current for a bond list of n bonds.
  bool valid_for(std::size_t n) const { return valid_ && n_ == n; }
  std::size_t size() const { return n_; }

  // Padded arrays (length padded()): particle indices, kind, lever arms, relative orientation.
  std::size_t padded() const { return i.size(); }
  std::vector<std::uint32_t> i, j;
  std::vector<std::uint8_t> kind;
  std::vector<double> rix, riy, riz, rjx, rjy, rjz;  ///< BondRef::ri, BondRef::rj
  std::vector<double> cw, cx, cy, cz;                ///< BondRef::c
  std::vector<double> strength;                      ///< Bond::strength
  /// Per batch: the kind shared by all its lanes, or 0xff when they mix.
  std::vector<std::uint8_t> batch_kind;

 private:
  /// Every array to n_ rounded up to a multiple of kLanes.
  void size_arrays();
  /// Padding lanes from n_ on repeat the last bond; batch kinds from batch `first_batch` on.
  void finish(std::size_t first_batch);
  std::size_t n_ = 0;
  bool valid_ = false;
};

/// The particle state a bond reads (arrays of the particle store) and the accumulators it adds to.
struct BondKernelIo {
  const Vec3* x;
  const Quat* q;
  const Vec3* v;
  const Vec3* omega;
  Vec3* f;
  Vec3* torque;
};

/// A bond that failed this evaluation: its index in the batch (= in bonds_) and how (bond_failure).
struct BrokenBond {
  std::uint32_t index;
  BondFailure mode;
};

/// Evaluates every bond of `bb`: intact bonds add their force and moment to io.f / io.torque (in
/// bond order: f[j] += F_j, f[i] -= F_j, t[i] += T_i, t[j] += T_j); bonds past their strength add
/// nothing and are appended to `broken` in ascending index. params[k]: the parameters of kind k.
void bond_kernel(const BondBatch& bb, const ParallelBondParams* params, std::size_t n_params, const BondKernelIo& io,
                 std::vector<BrokenBond>& broken);

}  // namespace hs::bonded

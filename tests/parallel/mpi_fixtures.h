// Helpers shared by the MPI tests: the world communicator, a system built twice on every rank,
// one copy kept serial (par::serial()) and one distributed, and their comparison by global id
// (particle states, bond sets, how a set of particles spreads over the ranks).
#pragma once

#include "../bonded/fixtures.h"
#include "bonded/contact_linear.h"
#include "parallel/comm.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <tuple>
#include <utility>
#include <vector>

namespace hs {
const par::Comm& test_world();  // mpi_main.cpp
}  // namespace hs

namespace hs::test {

inline const par::Comm& world() { return test_world(); }

using Builder = std::function<void(bonded::Engine&)>;

struct EnginePair {
  std::unique_ptr<bonded::Engine> serial, dist;
};

inline EnginePair make_pair_of(const bonded::EngineDef& d, const Builder& build, const bonded::ParallelDef& pd = {}) {
  EnginePair p{std::make_unique<bonded::Engine>(d), std::make_unique<bonded::Engine>(d)};
  build(*p.serial);
  build(*p.dist);
  p.dist->distribute(world(), pd);
  return p;
}

/// Largest |x_dist - x_serial| (per component) over all particles (all ranks); infinite when a
/// particle the distributed copy owns is missing from the serial one.
inline double max_position_difference(const bonded::Engine& dist, const bonded::Engine& serial) {
  const auto& a = dist.particles();
  const auto& b = serial.particles();
  double m = 0.0;
  for (std::size_t i = 0; i < a.owned(); ++i) {
    const auto j = b.local(a.gid[i]);
    if (j == bonded::ParticleStore::kNone) {  // (still join the collective below)
      m = INFINITY;
      break;
    }
    m = std::max(m, (a.x[i] - b.x[j]).cwiseAbs().maxCoeff());
  }
  return world().max(m);
}

/// The largest difference in position, velocity and spin over the particles with ids in
/// [from, to) (all ranks), and how many the distributed copy holds: a particle the serial copy
/// lacks counts as infinite.
struct StateDiff {
  double x = 0.0, v = 0.0, w = 0.0;
  std::int64_t count = 0;
};
inline StateDiff compare_state(const bonded::Engine& dist, const bonded::Engine& serial, GlobalId from, GlobalId to) {
  const auto& a = dist.particles();
  const auto& b = serial.particles();
  double m[3] = {0.0, 0.0, 0.0};
  std::int64_t n = 0;
  for (std::size_t i = 0; i < a.owned(); ++i) {
    if (a.gid[i] < from || a.gid[i] >= to) continue;
    ++n;
    const auto j = b.local(a.gid[i]);
    if (j == bonded::ParticleStore::kNone) {
      m[0] = m[1] = m[2] = INFINITY;
      continue;
    }
    m[0] = std::max(m[0], (a.x[i] - b.x[j]).cwiseAbs().maxCoeff());
    m[1] = std::max(m[1], (a.v[i] - b.v[j]).cwiseAbs().maxCoeff());
    m[2] = std::max(m[2], (a.omega[i] - b.omega[j]).cwiseAbs().maxCoeff());
  }
  world().max(m, 3);
  return {m[0], m[1], m[2], world().sum(n)};
}

/// A bond as (lower id, higher id, kind).
using BondKey = std::tuple<GlobalId, GlobalId, int>;

/// Every rank's bonds, gathered on rank 0 and sorted (empty elsewhere). Collective.
inline std::vector<BondKey> gathered_bonds(const bonded::Engine& e) {
  constexpr std::size_t kRec = 2 * sizeof(GlobalId) + sizeof(int);
  par::Bytes mine(e.bonds().size() * kRec);
  char* o = mine.data();
  for (const bonded::Bond& b : e.bonds()) {
    const int kind = static_cast<int>(b.kind);
    std::memcpy(o, &b.gi, sizeof(GlobalId));
    std::memcpy(o + sizeof(GlobalId), &b.gj, sizeof(GlobalId));
    std::memcpy(o + 2 * sizeof(GlobalId), &kind, sizeof(int));
    o += kRec;
  }
  const par::Bytes all = world().gather(mine, 0);
  std::vector<BondKey> out(all.size() / kRec);
  for (std::size_t k = 0; k < out.size(); ++k) {
    const char* r = all.data() + k * kRec;
    std::memcpy(&std::get<0>(out[k]), r, sizeof(GlobalId));
    std::memcpy(&std::get<1>(out[k]), r + sizeof(GlobalId), sizeof(GlobalId));
    std::memcpy(&std::get<2>(out[k]), r + 2 * sizeof(GlobalId), sizeof(int));
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// A serial engine's bonds, sorted as gathered_bonds gives them.
inline std::vector<BondKey> sorted_bonds(const bonded::Engine& e) {
  std::vector<BondKey> out;
  for (const bonded::Bond& b : e.bonds()) out.emplace_back(b.gi, b.gj, static_cast<int>(b.kind));
  std::sort(out.begin(), out.end());
  return out;
}

/// Ranks that own at least one particle with an id in [from, to), and bonds among them whose
/// ends sit on different ranks (counted on the rank that holds the bond).
inline std::pair<std::int64_t, std::int64_t> spread(const bonded::Engine& e, GlobalId from, GlobalId to) {
  const auto& p = e.particles();
  std::int64_t here = 0, across = 0;
  for (std::size_t i = 0; i < p.owned(); ++i) here |= p.gid[i] >= from && p.gid[i] < to;
  for (const bonded::Bond& b : e.bonds()) across += b.gi >= from && b.j >= p.owned();
  return {world().sum(here), world().sum(across)};
}

/// Ice with bonds of the given strength (Pa) and contact damping from restitution 0.3.
inline bonded::EngineDef ice_def(double strength, double mu = 0.3) {
  Ice ice;
  bonded::EngineDef d = no_field_def(ice);
  d.contact.mu = mu;
  d.contact.zeta_n = d.contact.zeta_t = bonded::damping_ratio_from_restitution(0.3);
  const double m = ice.cell_mass(), I = 0.4 * m * 0.25 * ice.D * ice.D;
  d.bond[0] = bonded::ParallelBondParams::from_stiffness(ice.kn(), ice.kn(), 0.5 * ice.D, strength, strength, 0.1,
                                                         0.5 * m, 0.5 * I);
  return d;
}

}  // namespace hs::test

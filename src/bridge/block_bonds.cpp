#include "bridge/block_bonds.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace hs::bridge {

using bonded::BondKind;
using bonded::BondKinematics;
using bonded::BondRef;
using bonded::BondResult;
using bonded::ParallelBondParams;
using bonded::ParticleStore;

namespace {

// Whether x lies on or in the block's box grown by `grow` along each of its axes.
bool on_box(const BlockBody& b, const Vec3& x, double grow) {
  const Vec3 l = b.orientation.conjugate() * (x - b.position);
  return (l.cwiseAbs() - b.half_extents).maxCoeff() <= grow;
}

}  // namespace

void BlockParticleBonds::set_block(std::uint32_t block, const BlockBody& body) {
  if (block >= blocks_.size()) {
    blocks_.resize(static_cast<std::size_t>(block) + 1);
    impulse_.resize(blocks_.size(), Vec3::Zero());
    angular_impulse_.resize(blocks_.size(), Vec3::Zero());
  }
  blocks_[block] = body;
}

void BlockParticleBonds::add_bond_at(const ParticleStore& ps, std::size_t index, std::uint32_t block,
                                     const Vec3& surface_point, const Vec3& normal) {
  if (index >= ps.size()) throw std::invalid_argument("BlockParticleBonds: unknown particle");
  add_bond_to(ps.gid[index], ps.x[index], ps.q[index], ps.radius[index], block, surface_point, normal);
  cached_index_.back() = static_cast<std::uint32_t>(index);
}

void BlockParticleBonds::add_bond_to(GlobalId gid, const Vec3& x, const Quat& q, double r, std::uint32_t block,
                                     const Vec3& surface_point, const Vec3& normal) {
  if (block >= blocks_.size()) throw std::invalid_argument("BlockParticleBonds: unknown block slot");
  const BlockBody& B = blocks_[block];
  const Vec3 anchor = B.orientation.conjugate() * (surface_point - r * normal - B.position);
  push_at_anchor(gid, x, q, r, block, anchor, ParticleStore::kNone);  // (looked up by id at the first evaluation)
}

void BlockParticleBonds::push_at_anchor(GlobalId gid, const Vec3& x, const Quat& q, double r, std::uint32_t block,
                                        const Vec3& anchor, std::uint32_t cached) {
  const BlockBody& B = blocks_[block];
  BlockParticleBond b;
  b.gid = gid;
  b.block = block;
  b.anchor = anchor;
  // The virtual particle's centre exactly as add_forces() will compute it, so the bond starts
  // stress free up to rounding.
  const Vec3 xv = B.position + B.orientation * b.anchor;
  if (!((xv - x).norm() > 0.25 * r)) throw std::invalid_argument("BlockParticleBonds: particle centre inside the block");
  b.ref = BondRef::at_rest(x, q, r, xv, B.orientation, r);
  bonds_.push_back(b);
  cached_index_.push_back(cached);
  ++n_intact_;
}

void BlockParticleBonds::add_bond(const ParticleStore& ps, GlobalId gid, std::uint32_t block) {
  if (block >= blocks_.size()) throw std::invalid_argument("BlockParticleBonds: unknown block slot");
  const std::uint32_t i = ps.local(gid);
  if (i == ParticleStore::kNone) throw std::invalid_argument("BlockParticleBonds: unknown particle id");
  const BlockBody& B = blocks_[block];
  const Vec3 l = B.orientation.conjugate() * (ps.x[i] - B.position);
  const Vec3 closest = l.cwiseMax(-B.half_extents).cwiseMin(B.half_extents);
  const Vec3 d = l - closest;
  const double dist = d.norm();
  if (!(dist > 0.0)) throw std::invalid_argument("BlockParticleBonds: particle centre inside the block");
  add_bond_at(ps, i, block, B.position + B.orientation * closest, B.orientation * (d / dist));
}

std::size_t BlockParticleBonds::bond_patch(const ParticleStore& ps, std::uint32_t block, const Vec3& anchor,
                                           const Vec3& normal, double area, double rel_tol, std::size_t first,
                                           std::size_t last) {
  if (block >= blocks_.size()) throw std::invalid_argument("bond_patch: unknown block slot");
  if (!(area > 0.0) || !(normal.norm() > 0.0)) throw std::invalid_argument("bond_patch: area and normal must be > 0");
  const Vec3 n = normal.normalized();
  const double R2 = area / kPi;
  const BlockBody& B = blocks_[block];
  std::size_t made = 0;
  last = std::min(last, ps.owned());
  for (std::size_t i = first; i < last; ++i) {
    const double r = ps.radius[i];
    const Vec3 rel = ps.x[i] - anchor;
    const double s = rel.dot(n);
    if (!(s > 0.0) || s > r * (1.0 + rel_tol)) continue;
    if ((rel - s * n).squaredNorm() > R2) continue;
    const Vec3 foot = ps.x[i] - s * n;
    if (!on_box(B, foot, r * rel_tol)) continue;
    add_bond_at(ps, i, block, foot, n);
    ++made;
  }
  return made;
}

std::size_t BlockParticleBonds::bond_touching(const ParticleStore& ps, std::uint32_t block, double rel_tol) {
  if (block >= blocks_.size()) throw std::invalid_argument("bond_touching: unknown block slot");
  const BlockBody& B = blocks_[block];
  std::size_t made = 0;
  for (std::size_t i = 0; i < ps.owned(); ++i) {
    const Vec3 l = B.orientation.conjugate() * (ps.x[i] - B.position);
    const Vec3 d = l - l.cwiseMax(-B.half_extents).cwiseMin(B.half_extents);
    const double dist = d.norm();
    if (!(dist > 0.0) || dist > ps.radius[i] * (1.0 + rel_tol)) continue;
    add_bond(ps, ps.gid[i], block);
    ++made;
  }
  return made;
}

std::vector<BlockParticleBond> BlockParticleBonds::take_all() {
  std::vector<BlockParticleBond> out;
  for (const BlockParticleBond& b : bonds_)
    if (!b.broken) out.push_back(b);
  bonds_.clear();
  cached_index_.clear();
  n_intact_ = 0;
  return out;
}

void BlockParticleBonds::remake(const ParticleStore& ps, const BlockParticleBond& b) {
  if (b.block >= blocks_.size()) throw std::invalid_argument("BlockParticleBonds: unknown block slot");
  const std::uint32_t i = ps.local(b.gid);
  if (i == ParticleStore::kNone) throw std::invalid_argument("BlockParticleBonds: unknown particle id");
  push_at_anchor(b.gid, ps.x[i], ps.q[i], ps.radius[i], b.block, b.anchor, i);
}

std::vector<ReleasedBond> BlockParticleBonds::bonds_of(std::uint32_t block) const {
  std::vector<ReleasedBond> out;
  for (const BlockParticleBond& b : bonds_)
    if (b.block == block && !b.broken)
      out.push_back({b.gid, blocks_[block].position + blocks_[block].orientation * b.anchor});
  return out;
}

std::vector<ReleasedBond> BlockParticleBonds::release_block(std::uint32_t block) {
  std::vector<ReleasedBond> out = bonds_of(block);
  std::size_t w = 0;
  for (std::size_t k = 0; k < bonds_.size(); ++k) {
    const BlockParticleBond& b = bonds_[k];
    if (b.block != block) {
      cached_index_[w] = cached_index_[k];
      bonds_[w++] = b;
      continue;
    }
    if (!b.broken) --n_intact_;
  }
  bonds_.resize(w);
  cached_index_.resize(w);
  return out;
}

std::uint32_t BlockParticleBonds::lookup(const ParticleStore& ps, std::size_t n_owned, std::size_t k) {
  // The store is reordered at neighbour rebuilds and loses/gains particles under MPI: trust the
  // cached index only while it still holds the same particle.
  std::uint32_t& c = cached_index_[k];
  const GlobalId gid = bonds_[k].gid;
  if (c < n_owned && ps.gid[c] == gid) return c;
  c = ps.local(gid);
  if (c == ParticleStore::kNone || c >= n_owned) c = ParticleStore::kNone;
  return c;
}

bonded::ForceSourceResult BlockParticleBonds::add_forces(ParticleStore& ps, std::size_t n_owned,
                                                         const bonded::ForceSourceContext& ctx) {
  if (record_) recorded_.clear();
  if (n_intact_ == 0) return {};
  const ParallelBondParams& p = ctx.def.bond[static_cast<int>(BondKind::Freeze)];
  const double h = ctx.history_dt;
  for (std::size_t k = 0; k < bonds_.size(); ++k) {
    BlockParticleBond& b = bonds_[k];
    if (b.broken) continue;
    const std::uint32_t i = lookup(ps, n_owned, k);
    if (i == ParticleStore::kNone) continue;  // not ours (MPI) or gone
    const BlockBody& B = blocks_[b.block];
    const Vec3 xv = B.position + B.orientation * b.anchor;
    const Vec3 vv = B.velocity + B.angular_velocity.cross(xv - B.position);
    const BondKinematics kin{ps.x[i], xv, ps.q[i], B.orientation, ps.v[i], vv, ps.omega[i], B.angular_velocity};
    const BondResult r = bonded::parallel_bond(p, b.ref, kin);
    const bonded::BondFailure mode = bonded::bond_failure(p, r.sigma, r.tau, r.crush);
    if (mode != bonded::BondFailure::None) {
      b.broken = true;
      --n_intact_;
      ++stats_.broken;  // compression breaks count here only
      if (mode == bonded::BondFailure::Tension) ++stats_.broken_tension;
      if (mode == bonded::BondFailure::Shear) ++stats_.broken_shear;
      continue;
    }
    ps.f[i] -= r.fj;
    ps.torque[i] += r.ti;
    if (record_)
      recorded_.push_back({b.block, xv, r.fj, std::max(r.sigma, 0.0) / p.sigma_c, r.tau / p.tau_c});
    if (h > 0.0) {
      impulse_[b.block] += h * r.fj;
      angular_impulse_[b.block] += h * ((xv - B.position).cross(r.fj) + r.tj);
    }
  }
  return {};  // a bond has no contact overlap
}

void BlockParticleBonds::take_impulses(std::vector<Vec3>& linear, std::vector<Vec3>& angular) {
  linear = impulse_;
  angular = angular_impulse_;
  std::fill(impulse_.begin(), impulse_.end(), Vec3::Zero());
  std::fill(angular_impulse_.begin(), angular_impulse_.end(), Vec3::Zero());
}

std::size_t BlockParticleBonds::sync_broken(const par::Comm& comm) {
  if (comm.parallel() && !bonds_.empty()) {
    std::vector<double> flag(bonds_.size());
    for (std::size_t k = 0; k < bonds_.size(); ++k) flag[k] = bonds_[k].broken ? 1.0 : 0.0;
    comm.max(flag.data(), static_cast<int>(flag.size()));
    for (std::size_t k = 0; k < bonds_.size(); ++k)
      if (flag[k] > 0.0 && !bonds_[k].broken) {
        bonds_[k].broken = true;
        --n_intact_;
      }
  }
  std::size_t w = 0;
  for (std::size_t k = 0; k < bonds_.size(); ++k) {
    if (bonds_[k].broken) continue;
    cached_index_[w] = cached_index_[k];
    bonds_[w++] = bonds_[k];
  }
  const std::size_t removed = bonds_.size() - w;
  bonds_.resize(w);
  cached_index_.resize(w);
  return removed;
}

std::size_t BlockParticleBonds::count(std::uint32_t block) const {
  std::size_t c = 0;
  for (const auto& b : bonds_) c += (b.block == block && !b.broken);
  return c;
}

double BlockParticleBonds::elastic_energy(const ParticleStore& ps, const bonded::EngineDef& def) const {
  const ParallelBondParams& p = def.bond[static_cast<int>(BondKind::Freeze)];
  double e = 0.0;
  for (const auto& b : bonds_) {
    if (b.broken) continue;
    const std::uint32_t i = ps.local(b.gid);
    if (i == ParticleStore::kNone || i >= ps.owned()) continue;
    const BlockBody& B = blocks_[b.block];
    const Vec3 xv = B.position + B.orientation * b.anchor;
    const Vec3 vv = B.velocity + B.angular_velocity.cross(xv - B.position);
    const BondKinematics kin{ps.x[i], xv, ps.q[i], B.orientation, ps.v[i], vv, ps.omega[i], B.angular_velocity};
    e += bonded::parallel_bond(p, b.ref, kin).energy;
  }
  return e;
}

std::size_t bond_joint_to_particles(BlockParticleBonds& bonds, std::uint32_t block, const Vec3& anchor,
                                    const Vec3& normal, double area, const ConversionReport& converted) {
  if (!(area > 0.0) || !(normal.norm() > 0.0))
    throw std::invalid_argument("bond_joint_to_particles: area and normal must be > 0");
  const Vec3 n = normal.normalized();
  const double R2 = area / kPi, r = converted.radius;
  const BlockBody& B = bonds.block(block);
  const std::vector<Vec3>& x = converted.sites;
  // Candidates: new particles on the converted side whose foot lies in the patch and on the
  // remaining block's box (grown by a radius); then the layer nearest the face.
  std::vector<std::size_t> cand;
  double s_min = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < x.size(); ++k) {
    const Vec3 rel = x[k] - anchor;
    const double s = rel.dot(n);
    if (!(s > 0.0) || (rel - s * n).squaredNorm() > R2) continue;
    if (!on_box(B, x[k] - s * n, r)) continue;
    cand.push_back(k);
    s_min = std::min(s_min, s);
  }
  std::size_t made = 0;
  for (std::size_t k : cand) {
    const double s = (x[k] - anchor).dot(n);
    // Half the HCP layer spacing sqrt(2/3) D: only the first layer.
    if (s > s_min + 0.5 * std::sqrt(2.0 / 3.0) * 2.0 * r) continue;
    bonds.add_bond_to(converted.first_gid + k, x[k], converted.orientation, r, block, x[k] - s * n, n);
    ++made;
  }
  return made;
}

}  // namespace hs::bridge

#include "particle_store.h"

#include <cassert>
#include <stdexcept>

namespace hs::bonded {

void ParticleStore::reserve(std::size_t n) {
  x.reserve(n); v.reserve(n); f.reserve(n); omega.reserve(n); torque.reserve(n);
  q.reserve(n); radius.reserve(n); inv_mass.reserve(n); inv_inertia.reserve(n);
  mass.reserve(n); buoyant_volume.reserve(n); gid.reserve(n); material.reserve(n);
  flags.reserve(n); bond_count.reserve(n);
}

std::size_t ParticleStore::add(const ParticleInit& p, GlobalId id) {
  if (n_ghost != 0) throw std::logic_error("ParticleStore::add: cannot add owned particles while ghosts exist");
  if (!(p.mass > 0.0) || !(p.radius > 0.0))
    throw std::invalid_argument("ParticleStore::add: particle mass and radius must be positive");
  const std::size_t i = x.size();
  x.push_back(p.x); v.push_back(p.v); f.push_back(Vec3::Zero());
  omega.push_back(p.omega); torque.push_back(Vec3::Zero());
  q.push_back(p.q.normalized());
  radius.push_back(p.radius);
  const bool frozen = (p.flags & kFlagFrozen) != 0;
  inv_mass.push_back(frozen ? 0.0 : 1.0 / p.mass);
  // Solid sphere, I = 2/5 m r^2. The lattice-cell mass model scales m, and the
  // inertia with it, so the rotational/translational frequency ratio is unchanged.
  inv_inertia.push_back(frozen ? 0.0 : 1.0 / (0.4 * p.mass * p.radius * p.radius));
  mass.push_back(p.mass);
  buoyant_volume.push_back(p.buoyant_volume);
  gid.push_back(id);
  material.push_back(p.material);
  flags.push_back(p.flags);
  bond_count.push_back(0);
  index_[id] = static_cast<std::uint32_t>(i);
  n_owned = x.size();
  if (id >= next_gid_) next_gid_ = id + 1;
  return i;
}

ParticleRecord ParticleStore::record(std::size_t i) const {
  return {x[i], v[i], omega[i], q[i], radius[i], inv_mass[i], inv_inertia[i], mass[i], buoyant_volume[i],
          gid[i], material[i], flags[i], bond_count[i]};
}

void ParticleStore::push(const ParticleRecord& r) {
  const std::size_t i = x.size();
  x.push_back(r.x); v.push_back(r.v); f.push_back(Vec3::Zero());
  omega.push_back(r.omega); torque.push_back(Vec3::Zero()); q.push_back(r.q);
  radius.push_back(r.radius); inv_mass.push_back(r.inv_mass); inv_inertia.push_back(r.inv_inertia);
  mass.push_back(r.mass); buoyant_volume.push_back(r.buoyant_volume); gid.push_back(r.gid);
  material.push_back(r.material); flags.push_back(r.flags); bond_count.push_back(r.bond_count);
  index_[r.gid] = static_cast<std::uint32_t>(i);
  if (r.gid >= next_gid_) next_gid_ = r.gid + 1;
}

void ParticleStore::truncate(std::size_t n) {
  if (n >= size()) return;
  for (std::size_t i = n; i < size(); ++i) index_.erase(gid[i]);
  x.resize(n); v.resize(n); f.resize(n); omega.resize(n); torque.resize(n); q.resize(n);
  radius.resize(n); inv_mass.resize(n); inv_inertia.resize(n); mass.resize(n);
  buoyant_volume.resize(n); gid.resize(n); material.resize(n); flags.resize(n); bond_count.resize(n);
  n_owned = std::min(n_owned, n);
  n_ghost = n - n_owned;
}

void ParticleStore::permute(const std::vector<std::uint32_t>& order) {
  assert(order.size() == n_owned);
  std::vector<char> done;
  permute_in_place(x, order, done); permute_in_place(v, order, done); permute_in_place(f, order, done);
  permute_in_place(omega, order, done); permute_in_place(torque, order, done); permute_in_place(q, order, done);
  permute_in_place(radius, order, done); permute_in_place(inv_mass, order, done);
  permute_in_place(inv_inertia, order, done); permute_in_place(mass, order, done);
  permute_in_place(buoyant_volume, order, done); permute_in_place(gid, order, done);
  permute_in_place(material, order, done); permute_in_place(flags, order, done);
  permute_in_place(bond_count, order, done);
  rebuild_index();
}

void ParticleStore::compact(const std::vector<char>& keep) {
  std::vector<std::uint32_t> order;
  for (std::uint32_t i = 0; i < n_owned; ++i)
    if (keep[i]) order.push_back(i);
  const std::size_t n_new = order.size();
  // Shrink owned range: build new arrays with kept owned particles then ghosts.
  for (std::size_t g = n_owned; g < size(); ++g) order.push_back(static_cast<std::uint32_t>(g));
  auto take = [&](auto& a) {
    std::remove_reference_t<decltype(a)> b;
    b.reserve(order.size());
    for (auto k : order) b.push_back(a[k]);
    a.swap(b);
  };
  take(x); take(v); take(f); take(omega); take(torque); take(q); take(radius);
  take(inv_mass); take(inv_inertia); take(mass); take(buoyant_volume); take(gid);
  take(material); take(flags); take(bond_count);
  n_owned = n_new;
  rebuild_index();
}

void ParticleStore::rebuild_index() {
  index_.clear();
  index_.reserve(size() * 2);
  for (std::size_t i = 0; i < size(); ++i) index_[gid[i]] = static_cast<std::uint32_t>(i);
}

void ParticleStore::clear_forces() {
  for (auto& a : f) a.setZero();
  for (auto& a : torque) a.setZero();
}

}  // namespace hs::bonded

// Inserting a bonded lattice into an engine that may already be running and distributed over
// MPI ranks (docs/parallel.md, "Conversion under MPI"): the particle side of turning a rigid
// block into particles.
//
// Every rank calls insert_lattice with the same sites and bonds (the rigid world is replicated,
// so every rank converts the same block at the same step). The rules that make the result equal
// to a serial insertion and independent of the rank count:
//   * overlap: each rank tests the sites against its owned particles; one max-reduction of the
//     drop mask gives every rank the same kept sites;
//   * ids: kept sites take consecutive ids, in site order, from the id counter, which is the same
//     on every rank (a global max at distribute() and at every insertion; every rank moves it on
//     past the new ids, whether it added any or not);
//   * particles: each rank adds the kept sites inside its box (par::Decomposition::rank_of);
//   * bonds: a bond lives on the owner of its lower id (as everywhere, engine_parallel.cpp); that
//     rank makes it from the site list, which every rank holds whole, so its reference frame needs
//     no partner; the partner is bound by id at the full exchange that follows, exactly as after a
//     migration, and a partner out of reach stops every rank (never a lost bond);
//   * attached bonds (existing particle -> new site): the existing particle has the lower id, so
//     its owner makes the bond from its own state and the site's, bound the same way.
#include "engine.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace hs::bonded {


std::vector<char> Engine::overlapping_sites(const std::vector<Vec3>& x, const std::vector<double>& radius) const {
  if (radius.size() != x.size()) throw std::invalid_argument("overlapping_sites: one radius per site");
  const std::size_t ns = x.size(), n = ps_.owned();
  std::vector<char> hit(ns, 0);
  if (n > 0 && ns > 0) {
    // Owned particles in a hash grid of cell h >= r_max + site r_max: an overlapping pair is
    // always in neighbouring cells.
    double rmax = 0.0, smax = 0.0;
    for (std::size_t j = 0; j < n; ++j) rmax = std::max(rmax, ps_.radius[j]);
    for (double r : radius) smax = std::max(smax, r);
    const double h = rmax + smax;
    auto cell = [h](const Vec3& p) { return (p / h).array().floor().cast<std::int64_t>().matrix().eval(); };
    // 21 bits per axis, offset so that negative cells map uniquely (|cell| < 2^20).
    auto key = [](std::int64_t cx, std::int64_t cy, std::int64_t cz) {
      return ((cx + (1 << 20)) << 42) | ((cy + (1 << 20)) << 21) | (cz + (1 << 20));
    };
    std::unordered_map<std::int64_t, std::vector<std::uint32_t>> cells;
    for (std::size_t j = 0; j < n; ++j) {
      const auto k = cell(ps_.x[j]);
      cells[key(k.x(), k.y(), k.z())].push_back(static_cast<std::uint32_t>(j));
    }
    for (std::size_t i = 0; i < ns; ++i) {
      const auto k = cell(x[i]);
      for (int dx = -1; dx <= 1 && !hit[i]; ++dx)
        for (int dy = -1; dy <= 1 && !hit[i]; ++dy)
          for (int dz = -1; dz <= 1 && !hit[i]; ++dz) {
            auto it = cells.find(key(k.x() + dx, k.y() + dy, k.z() + dz));
            if (it == cells.end()) continue;
            for (std::uint32_t j : it->second)
              if ((ps_.x[j] - x[i]).norm() < ps_.radius[j] + radius[i]) {
                hit[i] = 1;
                break;
              }
          }
    }
  }
  if (parallel() && ns > 0) {  // OR over the ranks (a maximum is exact)
    std::vector<double> m(hit.begin(), hit.end());
    comm_->max(m.data(), static_cast<int>(ns));
    for (std::size_t i = 0; i < ns; ++i) hit[i] = m[i] > 0.0;
  }
  return hit;
}

LatticeInsertReport Engine::insert_lattice(const LatticeInsert& lat) {
  const std::size_t ns = lat.sites.size();
  // Checks first: every rank holds the same input, so every rank refuses alike, before any
  // collective call and before anything is added.
  for (std::size_t k = 0; k < ns; ++k) {
    const ParticleInit& p = lat.sites[k];
    if (!(p.mass > 0.0) || !(p.radius > 0.0) || !p.x.allFinite())
      throw std::invalid_argument("insert_lattice: site " + std::to_string(k) +
                                  " needs a finite position and positive mass and radius");
  }
  std::vector<std::array<std::uint32_t, 2>> canon;
  canon.reserve(lat.bonds.size());
  for (const auto& b : lat.bonds) {
    if (b[0] >= ns || b[1] >= ns || b[0] == b[1])
      throw std::invalid_argument("insert_lattice: bond (" + std::to_string(b[0]) + ", " + std::to_string(b[1]) +
                                  ") names a site out of range or bonds a site to itself");
    canon.push_back({std::min(b[0], b[1]), std::max(b[0], b[1])});
  }
  std::sort(canon.begin(), canon.end());
  if (std::adjacent_find(canon.begin(), canon.end()) != canon.end())
    throw std::invalid_argument("insert_lattice: a bond is listed twice");
  // Attached bonds: a site in range, each (particle, site) once, and every particle owned by
  // exactly one rank (counted over the ranks, so every rank refuses alike).
  std::vector<std::pair<GlobalId, std::uint32_t>> att;
  att.reserve(lat.attach.size());
  double owned_here = 0.0;
  for (const auto& a : lat.attach) {
    if (a.site >= ns)
      throw std::invalid_argument("insert_lattice: attach to site " + std::to_string(a.site) + " out of range");
    att.emplace_back(a.particle, a.site);
    const std::uint32_t i = ps_.local(a.particle);
    owned_here += i != ParticleStore::kNone && i < ps_.owned() ? 1.0 : 0.0;
  }
  std::sort(att.begin(), att.end());
  if (std::adjacent_find(att.begin(), att.end()) != att.end())
    throw std::invalid_argument("insert_lattice: an attach bond is listed twice");
  if (parallel() && !lat.attach.empty()) owned_here = comm_->sum(owned_here);
  if (owned_here != static_cast<double>(lat.attach.size()))
    throw std::invalid_argument("insert_lattice: " + std::to_string(lat.attach.size() - static_cast<std::size_t>(owned_here)) +
                                " attach bond(s) name a particle the engine does not hold");

  std::vector<char> drop(ns, 0);
  if (lat.drop_overlapping) {
    std::vector<Vec3> x(ns);
    std::vector<double> r(ns);
    for (std::size_t k = 0; k < ns; ++k) {
      x[k] = lat.sites[k].x;
      r[k] = lat.sites[k].radius;
    }
    drop = overlapping_sites(x, r);
  }
  // Ids in site order from the shared counter (a double holds ids below 2^53 exactly).
  GlobalId first = ps_.next_gid();
  if (parallel()) first = static_cast<GlobalId>(comm_->max(static_cast<double>(first)));
  LatticeInsertReport rep;
  rep.first_gid = first;
  rep.gid.assign(ns, LatticeInsertReport::kDropped);
  GlobalId next = first;
  for (std::size_t k = 0; k < ns; ++k)
    if (!drop[k]) rep.gid[k] = next++;
  rep.particles_created = static_cast<std::size_t>(next - first);
  rep.particles_dropped = ns - rep.particles_created;
  // Bonds between kept sites, lower id first, in ascending id order (as bond_touching makes them).
  // Ids grow with the site index, so the lower id is the lower site.
  std::vector<NewBond> bonds;
  for (const auto& [a, b] : canon)
    if (!drop[a] && !drop[b]) bonds.push_back({rep.gid[a], rep.gid[b], a, b});
  rep.bonds_created = bonds.size();
  std::vector<LatticeInsert::Attach> attach;
  for (const auto& a : lat.attach)
    if (!drop[a.site]) attach.push_back(a);
  rep.attached = attach.size();

  if (!parallel()) {
    for (std::size_t k = 0; k < ns; ++k)
      if (!drop[k]) add_owned(lat.sites[k], rep.gid[k]);
    for (const NewBond& b : bonds) add_bond(b.gi, b.gj, lat.kind);
    for (const auto& a : attach) add_bond(a.particle, rep.gid[a.site], a.kind);
  } else {
    insert_distributed(lat, rep.gid, bonds, attach);
  }
  ps_.advance_gid(next);
  return rep;
}

void Engine::insert_distributed(const LatticeInsert& lat, const std::vector<GlobalId>& gid,
                                const std::vector<NewBond>& bonds, const std::vector<LatticeInsert::Attach>& attach) {
  const int me = comm_->rank();
  ++pstats_.exchanges;
  drop_ghosts();  // (owned particles can only be added while there are no ghosts)
  for (std::size_t k = 0; k < lat.sites.size(); ++k) {
    if (gid[k] == LatticeInsertReport::kDropped) continue;
    const ParticleInit& p = lat.sites[k];
    note_radius(p.radius);  // on every rank alike: skin and Eq. 2 must agree everywhere
    if (dom_.rank_of(p.x) == me) add_owned(p, gid[k]);
  }
  for (const NewBond& nb : bonds) {
    const ParticleInit& a = lat.sites[nb.si];
    const ParticleInit& b = lat.sites[nb.sj];
    max_bond_length_ = std::max(max_bond_length_, (b.x - a.x).norm());  // (the halo must reach it)
    if (dom_.rank_of(a.x) != me) continue;
    Bond bd;
    bd.gi = nb.gi;
    bd.gj = nb.gj;
    bd.i = ps_.local(nb.gi);
    bd.j = ParticleStore::kNone;  // bound by id in make_ghosts()
    bd.kind = lat.kind;
    // The store keeps normalised orientations: the same reference frame as add_bond makes.
    bd.ref = BondRef::at_rest(a.x, a.q.normalized(), a.radius, b.x, b.q.normalized(), b.radius);
    bd.strength = bond_strength(bd.gi, bd.gj, bd.kind);
    bonds_.push_back(bd);
  }
  // Attached bonds: the existing particle has the lower id (new ids come after every id in use),
  // so its owner holds the bond, made from its own state and the site's. (No ghosts now: local
  // means owned.) make_ghosts() reduces the longest bond over the ranks.
  for (const auto& at : attach) {
    const std::uint32_t i = ps_.local(at.particle);
    if (i == ParticleStore::kNone) continue;
    const ParticleInit& b = lat.sites[at.site];
    if (!(at.particle < gid[at.site])) throw std::logic_error("insert_lattice: an attached particle's id follows a new one");
    max_bond_length_ = std::max(max_bond_length_, (b.x - ps_.x[i]).norm());
    Bond bd;
    bd.gi = at.particle;
    bd.gj = gid[at.site];
    bd.i = i;
    bd.j = ParticleStore::kNone;
    bd.kind = at.kind;
    bd.ref = BondRef::at_rest(ps_.x[i], ps_.q[i], ps_.radius[i], b.x, b.q.normalized(), b.radius);
    bd.strength = bond_strength(bd.gi, bd.gj, bd.kind);
    bonds_.push_back(bd);
  }
  redistribute();  // new ghosts, every new bond bound to both ends, bond counts
  build_neighbors();
  forces_valid_ = false;
}

}  // namespace hs::bonded

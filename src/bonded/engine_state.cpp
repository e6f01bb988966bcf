// Engine checkpoint state (docs/output.md, "Checkpoints"): everything step() reads that a
// rebuilt engine would not already hold. The particle arrays are saved in store order, ghosts
// included, and the contact-pair list itself (with its tangential springs), so the next force
// sum runs over the same pairs in the same order; the positions at the last rebuild decide the
// next rebuild exactly as they would have. Kept apart from engine.cpp so that the kernels'
// data layout can change there: a new per-particle or per-pair array is one line here.
#include "bonded/engine.h"

#include "common/state_archive.h"

#include <array>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace hs::bonded {

namespace {

/// The break counters: checkpoints written before the compression count (4 counters, not 5)
/// load with it zero.
StepStats load_step_stats(const StateArchive& a, const std::string& key) {
  const std::string& b = a.bytes(key);
  constexpr std::size_t kBefore = offsetof(StepStats, bonds_broken_compression);
  if (b.size() != kBefore) return a.get_value<StepStats>(key);
  StepStats st;
  std::memcpy(static_cast<void*>(&st), b.data(), kBefore);
  return st;
}


struct MeshHistoryRecord {
  GlobalId gid;
  std::uint64_t feature;
  Vec3 xi;
};

struct PairHistoryRecord {
  GlobalId a, b;
  Vec3 xi;
};

struct CrushedRecord {
  GlobalId a, b;
  double set;
  Vec3 xi;
};

/// A bond without padding (Bond has a 1-byte kind before 8-byte fields: its padding bytes are
/// whatever the last copy left, and equal states must save equal bytes).
struct BondRecord {
  std::uint32_t i, j;
  GlobalId gi, gj;
  std::uint64_t kind;
  double ri[3], rj[3], c[4];  // BondRef: lever arms, q_j0^* q_i0 (w, x, y, z)
};

BondRecord to_record(const Bond& b) {
  return BondRecord{b.i, b.j, b.gi, b.gj, static_cast<std::uint64_t>(b.kind),
                    {b.ref.ri.x(), b.ref.ri.y(), b.ref.ri.z()}, {b.ref.rj.x(), b.ref.rj.y(), b.ref.rj.z()},
                    {b.ref.c.w(), b.ref.c.x(), b.ref.c.y(), b.ref.c.z()}};
}
Bond from_record(const BondRecord& r) {
  Bond b;
  b.i = r.i;
  b.j = r.j;
  b.gi = r.gi;
  b.gj = r.gj;
  b.kind = static_cast<BondKind>(r.kind);
  b.ref.ri = Vec3(r.ri[0], r.ri[1], r.ri[2]);
  b.ref.rj = Vec3(r.rj[0], r.rj[1], r.rj[2]);
  b.ref.c = Quat(r.c[0], r.c[1], r.c[2], r.c[3]);
  return b;
}

/// Flags and scalars of the engine, one record.
struct EngineScalars {
  double max_disp2, dt, min_radius, history_dt, time, halo, max_bond_length;
  std::uint64_t step, last_balance_step, n_owned, n_ghost, next_gid;
  std::uint64_t forces_valid, need_rebuild, dt_auto, distributed;  // 8-byte fields only: no padding
};

template <class T>
void put_nested(StateArchive& a, const std::string& key, const std::vector<std::vector<T>>& v) {
  std::vector<std::uint64_t> sizes;
  std::vector<T> flat;
  for (const auto& x : v) {
    sizes.push_back(x.size());
    flat.insert(flat.end(), x.begin(), x.end());
  }
  a.put(key + "_sizes", sizes);
  a.put(key, flat);
}

template <class T>
std::vector<std::vector<T>> get_nested(const StateArchive& a, const std::string& key) {
  const auto sizes = a.get<std::uint64_t>(key + "_sizes");
  const auto flat = a.get<T>(key);
  std::vector<std::vector<T>> out;
  std::size_t o = 0;
  for (const std::uint64_t n : sizes) {
    if (o + n > flat.size()) throw std::runtime_error("checkpoint entry '" + key + "' is truncated");
    out.emplace_back(flat.begin() + static_cast<std::ptrdiff_t>(o), flat.begin() + static_cast<std::ptrdiff_t>(o + n));
    o += n;
  }
  return out;
}

}  // namespace

void Engine::save_state(StateArchive& a, const std::string& p) const {
  const ParticleStore& s = ps_;
  a.put(p + "x", s.x);
  a.put(p + "v", s.v);
  a.put(p + "f", s.f);
  a.put(p + "omega", s.omega);
  a.put(p + "torque", s.torque);
  a.put(p + "q", s.q);
  a.put(p + "radius", s.radius);
  a.put(p + "inv_mass", s.inv_mass);
  a.put(p + "inv_inertia", s.inv_inertia);
  a.put(p + "mass", s.mass);
  a.put(p + "buoyant_volume", s.buoyant_volume);
  a.put(p + "gid", s.gid);
  a.put(p + "material", s.material);
  a.put(p + "flags", s.flags);
  a.put(p + "bond_count", s.bond_count);
  std::vector<BondRecord> bonds;
  bonds.reserve(bonds_.size());
  for (const Bond& b : bonds_) bonds.push_back(to_record(b));
  a.put(p + "bonds", bonds);
  a.put(p + "pairs", pairs_);
  std::vector<Vec3> wall_points;
  for (const auto& w : walls_) wall_points.push_back(w.point);
  a.put(p + "wall_points", wall_points);
  a.put(p + "wall_force", wall_force_);
  put_nested(a, p + "wall_history", wall_hist_);
  std::vector<Vec3> mesh_pos, mesh_loads;
  std::vector<std::uint64_t> mesh_contacts;
  std::vector<std::vector<MeshHistoryRecord>> mesh_hist;
  for (const auto& m : meshes_) {
    mesh_pos.push_back(m.position);
    mesh_loads.push_back(m.load.force);
    mesh_loads.push_back(m.load.moment);
    mesh_loads.insert(mesh_loads.end(), m.load.part_force.begin(), m.load.part_force.end());
    mesh_loads.insert(mesh_loads.end(), m.load.part_moment.begin(), m.load.part_moment.end());
    mesh_contacts.push_back(m.load.contacts);
    std::vector<MeshHistoryRecord> h;
    for (const auto& [k, xi] : m.history) h.push_back({k.gid, k.feature, xi});
    mesh_hist.push_back(std::move(h));
  }
  a.put(p + "mesh_position", mesh_pos);
  a.put(p + "mesh_loads", mesh_loads);
  a.put(p + "mesh_contacts", mesh_contacts);
  put_nested(a, p + "mesh_history", mesh_hist);
  a.put(p + "x_at_build", x_at_build_);
  // Water exposure as of the last rebuild (bonds broken since count from the next one): kinds
  // and face areas apart, so the records carry no padding bytes.
  std::vector<std::uint8_t> exposure_kind(exposure_.size());
  std::vector<std::array<double, 6>> exposure_area(exposure_.size());
  for (std::size_t i = 0; i < exposure_.size(); ++i) {
    exposure_kind[i] = exposure_[i].kind;
    exposure_area[i] = exposure_[i].area;
  }
  a.put(p + "exposure_kind", exposure_kind);
  a.put(p + "exposure_area", exposure_area);
  a.put_value(p + "stats", stats_);
  a.put_value(p + "parallel_stats", pstats_);
  const EngineScalars sc{max_disp2_, dt_, min_radius_, history_dt_, time_, halo_, max_bond_length_,
                     step_, last_balance_step_, s.n_owned, s.n_ghost, s.next_gid(),
                     forces_valid_, need_rebuild_, dt_auto_, distributed_};
  a.put_value(p + "scalars", sc);
  // Wall-clock figures (the "time" cost model's measure): the same physics with other timings.
  a.put_value(p + "parallel_stats_balance_seconds", force_seconds_since_balance_);
  // MPI: the cuts and the ghost exchange lists of the last rebuild.
  for (int ax = 0; ax < 3; ++ax) a.put(p + "cuts_" + std::to_string(ax), dom_.cuts(ax));
  a.put(p + "dims", std::vector<int>(dom_.dims().begin(), dom_.dims().end()));
  a.put(p + "peers", peers_);
  put_nested(a, p + "ghost_send", ghost_send_);
  a.put(p + "ghost_start", ghost_start_);
  a.put(p + "ghost_n", ghost_n_);
  std::vector<PairHistoryRecord> carried;
  for (const auto& [k, xi] : carried_history_) carried.push_back({k.a, k.b, xi});
  a.put(p + "carried_history", carried);
  std::vector<CrushedRecord> crushed;
  for (const auto& [k, c] : crushed_) crushed.push_back({k.a, k.b, c.set, c.xi});
  a.put(p + "crushed_pairs", crushed);
}

void Engine::load_mesh_poses_and_loads(const StateArchive& a, const std::string& p) {
  const auto mesh_pos = a.get<Vec3>(p + "mesh_position");
  const auto mesh_loads = a.get<Vec3>(p + "mesh_loads");
  const auto mesh_contacts = a.get<std::uint64_t>(p + "mesh_contacts");
  if (mesh_pos.size() != meshes_.size()) throw std::runtime_error("engine checkpoint: another number of mesh walls");
  std::size_t o = 0;  // per mesh: force, moment, then its parts' forces and moments
  for (std::size_t k = 0; k < meshes_.size(); ++k) {
    MeshWall& m = meshes_[k];
    m.position = mesh_pos[k];
    const std::size_t np = m.load.part_force.size();
    if (o + 2 + 2 * np > mesh_loads.size()) throw std::runtime_error("engine checkpoint: mesh loads truncated");
    m.load.force = mesh_loads[o];
    m.load.moment = mesh_loads[o + 1];
    std::copy(mesh_loads.begin() + o + 2, mesh_loads.begin() + o + 2 + np, m.load.part_force.begin());
    std::copy(mesh_loads.begin() + o + 2 + np, mesh_loads.begin() + o + 2 + 2 * np, m.load.part_moment.begin());
    o += 2 + 2 * np;
    m.load.contacts = mesh_contacts.at(k);
  }
}

void Engine::load_state(const StateArchive& a, const std::string& p) {
  const auto sc = a.get_value<EngineScalars>(p + "scalars");
  const auto dims = a.get<int>(p + "dims");
  if (dims.size() != 3 || (sc.distributed && (dims[0] * dims[1] * dims[2] != comm_->size() || !distributed_)))
    throw std::runtime_error("engine checkpoint: saved on another rank layout");
  ParticleStore& s = ps_;
  a.get_into(p + "x", s.x);
  a.get_into(p + "v", s.v);
  a.get_into(p + "f", s.f);
  a.get_into(p + "omega", s.omega);
  a.get_into(p + "torque", s.torque);
  a.get_into(p + "q", s.q);
  a.get_into(p + "radius", s.radius);
  a.get_into(p + "inv_mass", s.inv_mass);
  a.get_into(p + "inv_inertia", s.inv_inertia);
  a.get_into(p + "mass", s.mass);
  a.get_into(p + "buoyant_volume", s.buoyant_volume);
  a.get_into(p + "gid", s.gid);
  a.get_into(p + "material", s.material);
  a.get_into(p + "flags", s.flags);
  a.get_into(p + "bond_count", s.bond_count);
  const std::size_t n = s.x.size();
  for (std::size_t len : {s.v.size(), s.f.size(), s.omega.size(), s.torque.size(), s.q.size(), s.radius.size(),
                          s.inv_mass.size(), s.inv_inertia.size(), s.mass.size(), s.buoyant_volume.size(),
                          s.gid.size(), s.material.size(), s.flags.size(), s.bond_count.size()})
    if (len != n) throw std::runtime_error("engine checkpoint: particle arrays of different lengths");
  if (sc.n_owned + sc.n_ghost != n) throw std::runtime_error("engine checkpoint: particle counts disagree");
  s.n_owned = sc.n_owned;
  s.n_ghost = sc.n_ghost;
  s.advance_gid(sc.next_gid);
  s.rebuild_index();
  bonds_.clear();
  for (const BondRecord& r : a.get<BondRecord>(p + "bonds")) {
    bonds_.push_back(from_record(r));
    bonds_.back().strength = bond_strength(r.gi, r.gj, bonds_.back().kind);  // from the ids, as when made
  }
  a.get_into(p + "pairs", pairs_);
  const auto wall_points = a.get<Vec3>(p + "wall_points");
  if (wall_points.size() != walls_.size()) throw std::runtime_error("engine checkpoint: another number of walls");
  for (std::size_t k = 0; k < walls_.size(); ++k) walls_[k].point = wall_points[k];
  a.get_into(p + "wall_force", wall_force_);
  wall_hist_ = get_nested<Vec3>(a, p + "wall_history");
  load_mesh_poses_and_loads(a, p);
  const auto mesh_hist = get_nested<MeshHistoryRecord>(a, p + "mesh_history");
  if (mesh_hist.size() != meshes_.size()) throw std::runtime_error("engine checkpoint: another number of mesh walls");
  for (std::size_t k = 0; k < meshes_.size(); ++k) {
    MeshWall& m = meshes_[k];
    m.history.clear();
    m.next_history.clear();
    for (const auto& r : mesh_hist[k]) m.history.emplace(MeshWall::Key{r.gid, r.feature}, r.xi);
  }
  a.get_into(p + "x_at_build", x_at_build_);
  const auto exposure_kind = a.get<std::uint8_t>(p + "exposure_kind");
  const auto exposure_area = a.get<std::array<double, 6>>(p + "exposure_area");
  if (exposure_kind.size() != exposure_area.size())
    throw std::runtime_error("engine checkpoint: water exposure arrays of different lengths");
  exposure_.resize(exposure_kind.size());
  for (std::size_t i = 0; i < exposure_.size(); ++i) {
    exposure_[i].kind = static_cast<ParticleExposure::Kind>(exposure_kind[i]);
    exposure_[i].area = exposure_area[i];
  }
  stats_ = load_step_stats(a, p + "stats");
  pstats_ = a.get_value<ParallelStats>(p + "parallel_stats");
  max_disp2_ = sc.max_disp2;
  dt_ = sc.dt;
  min_radius_ = sc.min_radius;
  history_dt_ = sc.history_dt;
  time_ = sc.time;
  halo_ = sc.halo;
  max_bond_length_ = sc.max_bond_length;
  force_seconds_since_balance_ = a.get_value<double>(p + "parallel_stats_balance_seconds");
  step_ = sc.step;
  last_balance_step_ = sc.last_balance_step;
  forces_valid_ = sc.forces_valid != 0;
  need_rebuild_ = sc.need_rebuild != 0;
  dt_auto_ = sc.dt_auto != 0;
  if (distributed_) {
    for (int ax = 0; ax < 3; ++ax) dom_.set_cuts(ax, a.get<double>(p + "cuts_" + std::to_string(ax)));
    a.get_into(p + "peers", peers_);
    ghost_send_ = get_nested<std::uint32_t>(a, p + "ghost_send");
    a.get_into(p + "ghost_start", ghost_start_);
    a.get_into(p + "ghost_n", ghost_n_);
  }
  carried_history_.clear();
  for (const auto& r : a.get<PairHistoryRecord>(p + "carried_history")) carried_history_[GidPair{r.a, r.b}] = r.xi;
  load_crushed_pairs(a, p, true);
}

void Engine::load_crushed_pairs(const StateArchive& a, const std::string& p, bool clear) {
  if (clear) crushed_.clear();
  // A checkpoint from before crushed pairs has none; an engine without the set makes none.
  if (!a.has(p + "crushed_pairs") || !def_.crushed_set) return;
  for (const auto& r : a.get<CrushedRecord>(p + "crushed_pairs")) crushed_[GidPair{r.a, r.b}] = {r.set, r.xi};
}

void Engine::load_state_union(const std::vector<StateArchive>& all, const std::string& p) {
  if (all.empty()) throw std::runtime_error("engine checkpoint: no ranks");
  const auto sc = all[0].get_value<EngineScalars>(p + "scalars");
  // One system: every saved rank's owned particles, in rank order.
  ps_.truncate(0);
  ps_.n_owned = 0;
  carried_exposure_.clear();
  ps_.n_ghost = 0;
  bonds_.clear();
  pairs_.clear();
  carried_history_.clear();
  crushed_.clear();
  for (auto& m : meshes_) {
    m.history.clear();
    m.next_history.clear();
  }
  std::vector<std::vector<Vec3>> wall_hist(walls_.size());
  std::vector<BondRecord> bond_records;
  // The forces of the last step travel with their particles: evaluated again they would see the
  // rigid blocks where the next step puts them, not where the last step had them.
  std::unordered_map<GlobalId, std::pair<Vec3, Vec3>> force_of;
  // The positions at the last neighbour rebuild, by id: the restart rebuilds there (below), so
  // that the run's later rebuilds, and the water exposure that changes only at rebuilds, fall on
  // the steps of the run that was never stopped. Only where every saved rank's lists were
  // current (no rebuild due at the next step: then that rebuild is the run's own, as saved).
  std::unordered_map<GlobalId, Vec3> x_build_of;
  bool keep_schedule = true;
  for (const StateArchive& a : all) {
    const auto rs = a.get_value<EngineScalars>(p + "scalars");
    const auto x = a.get<Vec3>(p + "x"), v = a.get<Vec3>(p + "v"), w = a.get<Vec3>(p + "omega");
    const auto q = a.get<Quat>(p + "q");
    const auto radius = a.get<double>(p + "radius"), inv_mass = a.get<double>(p + "inv_mass"),
               inv_inertia = a.get<double>(p + "inv_inertia"), mass = a.get<double>(p + "mass"),
               buoyant = a.get<double>(p + "buoyant_volume");
    const auto gid = a.get<GlobalId>(p + "gid");
    const auto material = a.get<MaterialIndex>(p + "material");
    const auto flags = a.get<std::uint8_t>(p + "flags"), bond_count = a.get<std::uint8_t>(p + "bond_count");
    if (rs.n_owned > x.size() || gid.size() != x.size())
      throw std::runtime_error("engine checkpoint: particle counts disagree");
    const auto f = a.get<Vec3>(p + "f"), t = a.get<Vec3>(p + "torque");
    const auto exposure_kind = a.get<std::uint8_t>(p + "exposure_kind");
    const auto exposure_area = a.get<std::array<double, 6>>(p + "exposure_area");
    const auto x_at_build = a.get<Vec3>(p + "x_at_build");
    if (rs.need_rebuild != 0 || x_at_build.size() != x.size() || exposure_kind.size() < rs.n_owned ||
        exposure_area.size() != exposure_kind.size())
      keep_schedule = false;
    for (std::size_t i = 0; keep_schedule && i < rs.n_owned; ++i) {
      carried_exposure_[gid[i]] = ParticleExposure{static_cast<ParticleExposure::Kind>(exposure_kind[i]), exposure_area[i]};
      x_build_of[gid[i]] = x_at_build[i];
    }
    for (std::size_t i = 0; i < rs.n_owned; ++i) {
      ps_.push(ParticleRecord{x[i], v[i], w[i], q[i], radius[i], inv_mass[i], inv_inertia[i], mass[i], buoyant[i],
                              gid[i], material[i], flags[i], bond_count[i]});
      force_of[gid[i]] = {f.at(i), t.at(i)};
    }
    const auto hist = get_nested<Vec3>(a, p + "wall_history");
    if (hist.size() != walls_.size()) throw std::runtime_error("engine checkpoint: another number of walls");
    for (std::size_t k = 0; k < walls_.size(); ++k)
      wall_hist[k].insert(wall_hist[k].end(), hist[k].begin(), hist[k].begin() + static_cast<std::ptrdiff_t>(rs.n_owned));
    const auto b = a.get<BondRecord>(p + "bonds");
    bond_records.insert(bond_records.end(), b.begin(), b.end());
    // Tangential springs of contact pairs, by global ids (as a neighbour rebuild carries them).
    for (const ContactPair& c : a.get<ContactPair>(p + "pairs"))
      if (c.xi.squaredNorm() > 0.0)
        carried_history_.emplace(GidPair::of(gid[c.i], gid[c.j]), gid[c.i] < gid[c.j] ? c.xi : Vec3(-c.xi));
    for (const auto& r : a.get<PairHistoryRecord>(p + "carried_history")) carried_history_.emplace(GidPair{r.a, r.b}, r.xi);
    load_crushed_pairs(a, p, false);
    const auto mh = get_nested<MeshHistoryRecord>(a, p + "mesh_history");
    if (mh.size() != meshes_.size()) throw std::runtime_error("engine checkpoint: another number of mesh walls");
    for (std::size_t k = 0; k < meshes_.size(); ++k)
      for (const auto& r : mh[k]) meshes_[k].history.emplace(MeshWall::Key{r.gid, r.feature}, r.xi);
  }
  ps_.n_owned = ps_.size();
  ps_.advance_gid(sc.next_gid);
  ps_.rebuild_index();
  wall_hist_ = std::move(wall_hist);
  for (const BondRecord& r : bond_records) {
    Bond b = from_record(r);
    b.strength = bond_strength(b.gi, b.gj, b.kind);
    b.i = ps_.local(b.gi);
    b.j = ps_.local(b.gj);
    if (b.i == ParticleStore::kNone || b.j == ParticleStore::kNone)
      throw std::runtime_error("engine checkpoint: a bond names a particle no rank saved");
    bonds_.push_back(b);
  }
  // What is global (walls, meshes, counters, time) from rank 0.
  const StateArchive& a0 = all[0];
  const auto wall_points = a0.get<Vec3>(p + "wall_points");
  for (std::size_t k = 0; k < walls_.size(); ++k) walls_[k].point = wall_points.at(k);
  a0.get_into(p + "wall_force", wall_force_);
  load_mesh_poses_and_loads(a0, p);
  stats_ = load_step_stats(a0, p + "stats");
  pstats_ = ParallelStats{};
  dt_ = sc.dt;
  dt_auto_ = sc.dt_auto != 0;
  min_radius_ = sc.min_radius;
  time_ = sc.time;
  step_ = sc.step;
  history_dt_ = 0.0;
  max_bond_length_ = sc.max_bond_length;
  force_seconds_since_balance_ = 0.0;
  peers_.clear();
  ghost_send_.clear();
  ghost_start_.clear();
  ghost_n_.clear();
  if (!keep_schedule) carried_exposure_.clear();
  distribute_at_saved_rebuild(x_build_of, keep_schedule);
  for (std::size_t i = 0; i < ps_.owned(); ++i) {
    const auto& ft = force_of.at(ps_.gid[i]);
    ps_.f[i] = ft.first;
    ps_.torque[i] = ft.second;
  }
  max_disp2_ = 0.0;
  forces_valid_ = true;  // the first step kicks with those forces
}

void Engine::distribute_at_saved_rebuild(const std::unordered_map<GlobalId, Vec3>& x_build_of, bool keep_schedule) {
  // Rebuilding at the saved positions of the last rebuild: every rank owns, sees as ghosts and
  // pairs what it would have at that rebuild (the same pairs as the saved run: those within
  // r_i + r_j + skin then), and x_at_build_ is what the displacement trigger of the saved run
  // compares with (a global maximum: every rank count rebuilds on the same steps). Then the
  // positions of the checkpoint's step go back in, ghosts included.
  std::unordered_map<GlobalId, Vec3> x_now;
  if (keep_schedule) {
    x_now.reserve(ps_.size());
    for (std::size_t i = 0; i < ps_.size(); ++i) {
      x_now.emplace(ps_.gid[i], ps_.x[i]);
      ps_.x[i] = x_build_of.at(ps_.gid[i]);
    }
  }
  distributed_ = false;
  if (comm_->parallel()) distribute(*comm_, pdef_);  // every rank holds the whole system: spread it as a fresh build is
  if (keep_schedule) {
    build_neighbors();               // keeps the saved water exposure (carried_exposure_)
    --stats_.neighbor_rebuilds;      // not one of the run's own
    for (std::size_t i = 0; i < ps_.size(); ++i) ps_.x[i] = x_now.at(ps_.gid[i]);
  } else {  // the first step rebuilds the neighbour lists (and ghosts), as the saved run's would
    x_at_build_.assign(ps_.x.begin(), ps_.x.end());
    need_rebuild_ = true;
  }
}

}  // namespace hs::bonded

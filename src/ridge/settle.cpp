// Compaction and settling in the rigid world (docs/ridge.md, Method 4), through RigidWorld's
// public API: the world of the ice, the end walls and the placed blocks, the two phases, and
// the settled poses, energies and vertical balance collected from it.
#include "ridge/internal.h"

#include "rigid/box_water.h"

namespace hs::rigid::detail {

RigidWorldDef settle_world_def(const RidgeDef& d) {
  RigidWorldDef wd;
  wd.dt = d.settle.dt;
  wd.solver_iterations = d.settle.solver_iterations;
  wd.water = true;
  wd.water_level = 0.0;
  wd.water_density = d.water_density;
  wd.linear_drag = d.settle.linear_drag;
  wd.quadratic_drag_cd = d.settle.quadratic_drag_cd;
  wd.friction = d.settle.friction;
  wd.restitution = 0.0;
  wd.fixed_friction_directions = d.settle.fixed_friction_directions;
  wd.allow_sleep = d.settle.allow_sleep;
  wd.sleep_linear_velocity = 0.02;
  wd.sleep_angular_velocity = 0.02;
  wd.freeze_bond_strength = std::numeric_limits<double>::infinity();  // the plates' joints hold
  return wd;
}

namespace {

/// The rigid world of the settling: end walls fixed, the ice fixed or floating plates (heave
/// only), blocks released at rest. Returns the blocks' ids in `placed` order; the ice boxes'
/// ids go to `ice_ids`.
std::vector<BlockId> build_settle_world(RigidWorld& world, const RidgeRun& run, const std::vector<IceBox>& ice,
                                        const std::vector<Placed>& placed, std::vector<BlockId>& ice_ids) {
  const RidgeDef& d = run.d;
  double zmin = 0.0, zmax = 0.0;
  for (const Placed& p : placed) {
    zmin = std::min(zmin, p.x.z() - p.aabb.z());
    zmax = std::max(zmax, p.x.z() + p.aabb.z());
  }
  for (const IceBox& b : ice) {
    BlockDef bd;
    bd.half_extents = b.half_extents;
    bd.position = b.position;
    if (d.sheet.floating) {
      bd.density = plate_density(b.position.z() + b.half_extents.z(), b.position.z() - b.half_extents.z(),
                                 d.water_density);
      bd.linear_factor = Vec3::UnitZ();
      bd.angular_factor = Vec3::Zero();
    } else {
      bd.fixed = true;
    }
    ice_ids.push_back(world.add_block(bd));
  }
  if (d.sheet.floating && d.sheet.plates_joined) {
    // Fixed joints between neighbours (the settle world's joints never break: its strength is
    // infinite), anchored at the middle of their common edge.
    for (std::size_t k = 0; k + 1 < ice.size(); ++k) {
      FreezeJointDef j;
      j.a = ice_ids[k];
      j.b = ice_ids[k + 1];
      j.anchor = Vec3(0.5 * (ice[k].position.x() + ice[k].half_extents.x() + ice[k + 1].position.x() -
                             ice[k + 1].half_extents.x()),
                      ice[k].position.y(), std::min(ice[k].position.z(), ice[k + 1].position.z()));
      j.normal = Vec3::UnitX();
      j.area = 1.0;
      world.add_freeze_joint(j);
    }
  }
  if (d.end_walls) {
    for (int s = 0; s < 2; ++s) {
      BlockDef bd;
      bd.half_extents = Vec3(run.ice_half + 5.0, 1.0, 0.5 * (zmax - zmin) + 5.0);
      bd.position = Vec3(0.0, s == 0 ? -1.0 : d.length + 1.0, 0.5 * (zmax + zmin));
      bd.fixed = true;
      world.add_block(bd);
    }
  }
  std::vector<BlockId> ids;
  ids.reserve(placed.size());
  for (const Placed& p : placed) {
    BlockDef bd;
    bd.half_extents = p.h;
    bd.position = p.x;
    bd.orientation = p.q;
    bd.density = d.ice_density;
    ids.push_back(world.add_block(bd));
  }
  return ids;
}

// ---- settle, in two phases (docs/ridge.md, Method 4). Compaction: the keel blocks'
// friction lowered to compaction_friction so the rising blocks slide into the voids of
// the pile (a numerical stand-in for the reworking a real keel gets while the ridge is
// pushed together; it is not the friction of the final state); sail blocks keep theirs.
// Settle: the physical friction back, more solver iterations, and a velocity-
// proportional damping (rate settle.damping, implicit) against the residual creep and
// solver jitter of a deep pile. Each phase ends when the mean kinetic energy per block
// stays below the threshold for 1 s (after min_time in that phase).
class Settling {
 public:
  Settling(const RidgeRun& run, RigidWorld& world, const std::vector<BlockId>& ids, const std::vector<Placed>& placed)
      : run_(run), d_(run.d), world_(world), ids_(ids), placed_(placed), n_(placed.size()),
        check_every_(std::max(1, static_cast<int>(std::lround(0.25 / run.d.settle.dt)))),
        ring_(static_cast<int>(std::ceil(1.0 / (check_every_ * run.d.settle.dt) - 1e-9)) + 1), snaps_(ring_) {}

  /// Runs compaction and settling; fills the settle figures of `st`. Returns the last mean
  /// kinetic energy per block, J.
  double run(RidgeStats& st) {
    const double vcap = d_.settle.speed_cap_factor * d_.block_thickness / d_.settle.dt;
    double below = 0.0, ke = 0.0;
    bool settled = false, compacting = d_.settle.compaction_time > 0.0;
    std::uint64_t steps = 0;
    if (compacting) {
      set_keel_friction(d_.settle.compaction_friction);
      world_.set_solver_iterations(d_.settle.compaction_solver_iterations);
    }
    double phase_start = 0.0;
    if (n_ > 0) snapshot();
    while (n_ > 0) {
      world_.substep();
      ++steps;
      cap_and_damp(vcap, compacting ? 1.0 : 1.0 / (1.0 + d_.settle.damping * d_.settle.dt));
      if (steps % check_every_ != 0) continue;
      const double t = world_.time();
      ke = world_.kinetic_energy() / static_cast<double>(n_);
      snapshot();
      const double moved = last_second_max_displacement();
      run_.report(compacting ? "compact" : "settle", t, ke, n_, moved);
      bool phase_done = false;
      // The displacement test is the settle phase's (compaction ends at its time anyway).
      const bool still = compacting || !(d_.settle.max_displacement > 0.0) ||
                         (t - phase_start >= 1.0 && moved < d_.settle.max_displacement);
      if (t - phase_start >= d_.settle.min_time && ke < d_.settle.kinetic_energy_per_block && still) {
        below += check_every_ * d_.settle.dt;
        phase_done = below >= 1.0 - 1e-9;
      } else {
        below = 0.0;
      }
      if (compacting && (phase_done || t >= d_.settle.compaction_time)) {
        compacting = false;
        st.compaction_time = t;
        set_keel_friction(d_.settle.friction);
        world_.set_solver_iterations(d_.settle.solver_iterations);
        phase_start = t;
        below = 0.0;
        continue;
      }
      if (phase_done) {
        settled = true;
        break;
      }
      if (t >= d_.settle.max_time) break;
    }
    final_displacement(st);
    st.settled = settled || n_ == 0;
    st.settle_time = world_.time();
    st.settle_steps = steps;
    st.final_kinetic_energy_per_block = ke;
    return ke;
  }

 private:
  /// Only keel blocks: keel-keel and keel-ice contacts lose their friction (the combined
  /// coefficient is a product), sail blocks keep theirs on the ice and on each other.
  void set_keel_friction(double mu) {
    for (std::size_t i = 0; i < n_; ++i)
      if (placed_[i].part == 0) world_.set_friction(ids_[i], mu);
  }
  /// Speed cap (translation and rim speed of the rotation) and the settling damping.
  void cap_and_damp(double vcap, double damp) {
    for (std::size_t i = 0; i < n_; ++i) {
      Vec3 v = world_.velocity(ids_[i]);
      Vec3 w = world_.angular_velocity(ids_[i]);
      const double sv = v.norm(), sw = w.norm() * placed_[i].h.maxCoeff();
      if (sv > vcap) v *= vcap / sv;
      if (sw > vcap) w *= vcap / sw;
      if (sv > vcap || sw > vcap || damp != 1.0) world_.set_velocity(ids_[i], v * damp, w * damp);
    }
  }
  /// Positions at the last checks (a ring over >= 1 s): the displacement over the final
  /// second is reported next to the kinetic energy, as a direct measure of rest.
  void snapshot() {
    std::vector<Vec3>& v = snaps_[nsnap_++ % ring_];
    v.resize(n_);
    for (std::size_t i = 0; i < n_; ++i) v[i] = world_.position(ids_[i]);
  }
  /// The oldest snapshot in the ring (<= 1 s ago) and the newest; needs nsnap_ >= 2.
  const std::vector<Vec3>& oldest_snapshot() const {
    return snaps_[nsnap_ >= static_cast<std::uint64_t>(ring_) ? nsnap_ % ring_ : 0];
  }
  const std::vector<Vec3>& newest_snapshot() const { return snaps_[(nsnap_ - 1) % ring_]; }
  /// Largest block displacement since the oldest snapshot in the ring, m.
  double last_second_max_displacement() const {
    if (nsnap_ < 2) return std::numeric_limits<double>::infinity();
    const std::vector<Vec3>& old = oldest_snapshot();
    const std::vector<Vec3>& now = newest_snapshot();
    double m = 0.0;
    for (std::size_t i = 0; i < n_; ++i) m = std::max(m, (now[i] - old[i]).norm());
    return m;
  }
  void final_displacement(RidgeStats& st) const {
    if (nsnap_ < 2) return;  // displacement since the oldest snapshot in the ring (<= 1 s ago)
    const std::vector<Vec3>& old = oldest_snapshot();
    const std::vector<Vec3>& now = newest_snapshot();
    double sum = 0.0;
    for (std::size_t i = 0; i < n_; ++i) {
      const double dd = (now[i] - old[i]).norm();
      sum += dd;
      st.final_max_displacement = std::max(st.final_max_displacement, dd);
    }
    st.final_mean_displacement = sum / static_cast<double>(n_);
  }

  const RidgeRun& run_;
  const RidgeDef& d_;
  RigidWorld& world_;
  const std::vector<BlockId>& ids_;
  const std::vector<Placed>& placed_;
  const std::size_t n_;
  const int check_every_;
  const int ring_;
  std::vector<std::vector<Vec3>> snaps_;
  std::uint64_t nsnap_ = 0;
};

/// Where the final kinetic energy sits. A Bullet body asleep has its velocities set to
/// exactly zero (and counts 0 in ke); an awake body never has exactly zero velocity.
void final_energy_stats(const RigidWorld& world, const std::vector<BlockId>& ids, const std::vector<Placed>& placed,
                        RidgeStats& st) {
  const std::size_t n = placed.size();
  if (n == 0) return;
  std::vector<double> eb(n);
  double esail = 0.0, etot = 0.0;
  std::size_t asleep = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 v = world.velocity(ids[i]), w = world.angular_velocity(ids[i]);
    if (v.isZero(0.0) && w.isZero(0.0)) ++asleep;
    const Vec3 wl = world.orientation(ids[i]).toRotationMatrix().transpose() * w;
    const Vec3& h = placed[i].h;
    const double m = world.mass(ids[i]);
    const Vec3 inertia = m / 3.0 * Vec3(h.y() * h.y() + h.z() * h.z(), h.x() * h.x() + h.z() * h.z(),
                                        h.x() * h.x() + h.y() * h.y());
    eb[i] = 0.5 * m * v.squaredNorm() + 0.5 * wl.dot(inertia.cwiseProduct(wl));
    etot += eb[i];
    if (placed[i].part != 0) esail += eb[i];
  }
  st.final_asleep_blocks = asleep;
  st.final_kinetic_energy_per_awake_block = asleep < n ? etot / static_cast<double>(n - asleep) : 0.0;
  st.final_kinetic_energy_sail_fraction = etot > 0.0 ? esail / etot : 0.0;
  std::nth_element(eb.begin(), eb.begin() + n / 2, eb.end());
  st.final_kinetic_energy_median = eb[n / 2];
}

/// The settled blocks into the result (and back into `placed`, for the joints and the report).
void collect_blocks(const RigidWorld& world, const std::vector<BlockId>& ids, std::vector<Placed>& placed,
                    RidgeResult& res) {
  const std::size_t n = placed.size();
  res.blocks.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    RidgeBlock& b = res.blocks[i];
    b.half_extents = placed[i].h;
    b.position = world.position(ids[i]);
    b.orientation = world.orientation(ids[i]);
    if (b.orientation.w() < 0.0) b.orientation.coeffs() *= -1.0;  // canonical sign
    b.part = placed[i].part;
    placed[i].x = b.position;
    placed[i].q = b.orientation;
    placed[i].R = b.orientation.toRotationMatrix();
    placed[i].aabb = aabb_half(placed[i].h, placed[i].R);
    if (b.part == 0) ++res.stats.keel_blocks;
    else ++res.stats.sail_blocks;
  }
}

/// The plates' final poses (heave only) and lifts; the vertical force balance of the whole.
void collect_plates(const RigidWorld& world, const std::vector<BlockId>& ice_ids, RidgeResult& res) {
  const RidgeDef& d = res.def;
  const double g = 9.81;
  auto net_buoyancy = [&](const Vec3& h, const Vec3& x, const Quat& q, double density) {
    const SubmergedBox sb = submerged_box(h, x, q, 0.0);
    return g * (d.water_density * sb.volume - density * 8.0 * h.prod());
  };
  res.stats.block_net_buoyancy = 0.0;
  for (const RidgeBlock& b : res.blocks)
    res.stats.block_net_buoyancy += net_buoyancy(b.half_extents, b.position, b.orientation, d.ice_density);
  res.stats.plate_net_buoyancy = 0.0;
  if (!d.sheet.floating) return;
  for (std::size_t k = 0; k < res.ice.size(); ++k) {
    IceBox& b = res.ice[k];
    const double rest = b.position.z();
    const double rho = plate_density(rest + b.half_extents.z(), rest - b.half_extents.z(), d.water_density);
    b.position = world.position(ice_ids[k]);
    b.lift = b.position.z() - rest;
    res.stats.plate_net_buoyancy += net_buoyancy(b.half_extents, b.position, Quat::Identity(), rho);
  }
}

}  // namespace

double settle_blocks(const RidgeRun& run, std::vector<Placed>& placed, RidgeResult& res) {
  RigidWorld world(settle_world_def(run.d));
  std::vector<BlockId> ice_ids;
  const std::vector<BlockId> ids = build_settle_world(world, run, res.ice, placed, ice_ids);
  const double ke = Settling(run, world, ids, placed).run(res.stats);
  final_energy_stats(world, ids, placed, res.stats);
  collect_blocks(world, ids, placed, res);
  collect_plates(world, ice_ids, res);
  return ke;
}

}  // namespace hs::rigid::detail

// Checkpoint state of the hybrid system (docs/output.md, "Checkpoints"): the rigid world, the
// particle-block contact and bonds, and the stepper's own bookkeeping.
#include "bridge/block_bonds.h"
#include "bridge/block_contact.h"
#include "bridge/hybrid.h"
#include "bridge/hybrid_impl.h"

#include "common/state_archive.h"

#include <stdexcept>
#include <type_traits>

namespace hs::bridge {

namespace {

struct ContactHistoryRecord {
  GlobalId gid;
  std::uint64_t block;
  Vec3 xi;
};

// The block tables as records without padding: ContactBlock and BlockBody hold an Eigen
// quaternion (16- or 32-byte aligned), so a raw copy would write whatever the padding bytes hold
// and two equal states would give two different checkpoints.
struct ContactBlockRecord {
  std::uint64_t id;
  double half_extents[3], position[3], orientation[4], velocity[3], angular_velocity[3], mass, friction;
};
struct BlockBodyRecord {
  double position[3], orientation[4], velocity[3], angular_velocity[3], half_extents[3];
};
static_assert(sizeof(ContactBlockRecord) == 8 + 18 * 8 && sizeof(BlockBodyRecord) == 16 * 8, "records without padding");

void put3(double* o, const Vec3& v) { o[0] = v.x(), o[1] = v.y(), o[2] = v.z(); }
void putq(double* o, const Quat& q) { o[0] = q.w(), o[1] = q.x(), o[2] = q.y(), o[3] = q.z(); }
Vec3 get3(const double* i) { return Vec3(i[0], i[1], i[2]); }
Quat getq(const double* i) { return Quat(i[0], i[1], i[2], i[3]); }

std::vector<ContactBlockRecord> contact_block_records(const std::vector<ContactBlock>& blocks) {
  std::vector<ContactBlockRecord> out(blocks.size());
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const ContactBlock& b = blocks[k];
    ContactBlockRecord& r = out[k];
    r.id = b.id;
    put3(r.half_extents, b.half_extents), put3(r.position, b.position), putq(r.orientation, b.orientation);
    put3(r.velocity, b.velocity), put3(r.angular_velocity, b.angular_velocity);
    r.mass = b.mass, r.friction = b.friction;
  }
  return out;
}
std::vector<ContactBlock> contact_blocks(const std::vector<ContactBlockRecord>& records) {
  std::vector<ContactBlock> out(records.size());
  for (std::size_t k = 0; k < records.size(); ++k) {
    const ContactBlockRecord& r = records[k];
    out[k] = {r.id, get3(r.half_extents), get3(r.position), getq(r.orientation), get3(r.velocity),
              get3(r.angular_velocity), r.mass, r.friction};
  }
  return out;
}
std::vector<BlockBodyRecord> block_body_records(const std::vector<BlockBody>& blocks) {
  std::vector<BlockBodyRecord> out(blocks.size());
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const BlockBody& b = blocks[k];
    BlockBodyRecord& r = out[k];
    put3(r.position, b.position), putq(r.orientation, b.orientation), put3(r.velocity, b.velocity);
    put3(r.angular_velocity, b.angular_velocity), put3(r.half_extents, b.half_extents);
  }
  return out;
}
std::vector<BlockBody> block_bodies(const std::vector<BlockBodyRecord>& records) {
  std::vector<BlockBody> out(records.size());
  for (std::size_t k = 0; k < records.size(); ++k) {
    const BlockBodyRecord& r = records[k];
    out[k] = {get3(r.position), getq(r.orientation), get3(r.velocity), get3(r.angular_velocity),
              get3(r.half_extents)};
  }
  return out;
}

/// A block-particle bond without padding (see BondRecord in bonded/engine_state.cpp).
struct BlockBondRecord {
  GlobalId gid;
  std::uint64_t block, broken;
  double anchor[3], ri[3], rj[3], c[4];
};

}  // namespace

void BlockContact::save_state(StateArchive& a, const std::string& p) const {
  a.put(p + "blocks", contact_block_records(blocks_));
  a.put(p + "loads", loads_);
  std::vector<ContactHistoryRecord> h;
  h.reserve(history_.size());
  for (const auto& [k, xi] : history_) h.push_back({k.gid, k.block, xi});
  a.put(p + "history", h);
  a.put(p + "rot", rot_);
}

void BlockContact::load_state(const StateArchive& a, const std::string& p) {
  blocks_ = contact_blocks(a.get<ContactBlockRecord>(p + "blocks"));
  a.get_into(p + "loads", loads_);
  if (loads_.size() != blocks_.size()) throw std::runtime_error("block contact checkpoint: loads and blocks differ");
  history_.clear();
  next_history_.clear();
  for (const auto& r : a.get<ContactHistoryRecord>(p + "history")) history_.emplace(Key{r.gid, r.block}, r.xi);
  a.get_into(p + "rot", rot_);
  dirty_.assign(blocks_.size(), 1);  // rot_ and ext_ recomputed from the restored poses
  recorded_.clear();
}

void BlockParticleBonds::save_state(StateArchive& a, const std::string& p) const {
  a.put(p + "blocks", block_body_records(blocks_));
  std::vector<BlockBondRecord> bonds;
  for (const BlockParticleBond& b : bonds_)
    bonds.push_back({b.gid, b.block, b.broken ? 1u : 0u, {b.anchor.x(), b.anchor.y(), b.anchor.z()},
                     {b.ref.ri.x(), b.ref.ri.y(), b.ref.ri.z()}, {b.ref.rj.x(), b.ref.rj.y(), b.ref.rj.z()},
                     {b.ref.c.w(), b.ref.c.x(), b.ref.c.y(), b.ref.c.z()}});
  a.put(p + "bonds", bonds);
  a.put(p + "cached_index", cached_index_);
  a.put(p + "impulse", impulse_);
  a.put(p + "angular_impulse", angular_impulse_);
  a.put_value(p + "intact", static_cast<std::uint64_t>(n_intact_));
  a.put_value(p + "stats", stats_);
}

void BlockParticleBonds::load_state(const StateArchive& a, const std::string& p) {
  blocks_ = block_bodies(a.get<BlockBodyRecord>(p + "blocks"));
  bonds_.clear();
  for (const BlockBondRecord& r : a.get<BlockBondRecord>(p + "bonds")) {
    BlockParticleBond b;
    b.gid = r.gid;
    b.block = static_cast<std::uint32_t>(r.block);
    b.broken = r.broken != 0;
    b.anchor = Vec3(r.anchor[0], r.anchor[1], r.anchor[2]);
    b.ref.ri = Vec3(r.ri[0], r.ri[1], r.ri[2]);
    b.ref.rj = Vec3(r.rj[0], r.rj[1], r.rj[2]);
    b.ref.c = Quat(r.c[0], r.c[1], r.c[2], r.c[3]);
    bonds_.push_back(b);
  }
  a.get_into(p + "cached_index", cached_index_);
  a.get_into(p + "impulse", impulse_);
  a.get_into(p + "angular_impulse", angular_impulse_);
  n_intact_ = static_cast<std::size_t>(a.get_value<std::uint64_t>(p + "intact"));
  stats_ = a.get_value<BlockBondStats>(p + "stats");
  recorded_.clear();
}

namespace {

// The report's counters that change while the run goes (the rest is set again by the build).
std::vector<std::uint64_t> report_counts(const HybridReport& r) {
  return {r.conversions,         r.particles_created,        r.bonds_created,          r.sites_dropped,
          static_cast<std::uint64_t>(r.peak_particles),       r.rigid_steps,            r.conversions_freeze,
          r.conversions_flexure, r.joints_released,          r.conversions_refused,    r.blocks_now,
          r.ice_bonds_created,   r.block_bonds_handed_over,  r.block_bonds_unmatched,  r.joints_to_bonds};
}
void set_report_counts(HybridReport& r, const std::vector<std::uint64_t>& c) {
  if (c.size() != 15) throw std::runtime_error("hybrid checkpoint: report counters of another version");
  std::uint64_t peak = 0;
  std::uint64_t blocks_now = 0;
  std::uint64_t* dst[15] = {&r.conversions,         &r.particles_created,       &r.bonds_created,
                            &r.sites_dropped,       &peak,                      &r.rigid_steps,
                            &r.conversions_freeze,  &r.conversions_flexure,     &r.joints_released,
                            &r.conversions_refused, &blocks_now,                &r.ice_bonds_created,
                            &r.block_bonds_handed_over, &r.block_bonds_unmatched, &r.joints_to_bonds};
  for (int k = 0; k < 15; ++k) *dst[k] = c[static_cast<std::size_t>(k)];
  r.peak_particles = static_cast<std::int64_t>(peak);
  r.blocks_now = static_cast<std::size_t>(blocks_now);
}

}  // namespace

void HybridSystem::save_state(StateArchive& a, const std::string& p) const {
  const Impl& m = *impl_;
  a.put(p + "report_counts", report_counts(report_));
  a.put(p + "report_by_criterion", report_.conversions_by_criterion);
  const double rd[5] = {report_.max_utilisation, report_.seconds_rigid, report_.seconds_bonded,
                        report_.seconds_bridge, report_.kinetic_energy_change};
  a.put(p + "report_doubles", std::vector<double>(rd, rd + 5));
  // The step's other wall times (HybridReport), a key of their own: a restart carries them on.
  a.put(p + "report_seconds", std::vector<double>{report_.seconds_bonded_force, report_.seconds_bonded_mpi,
                                                  report_.seconds_stress, report_.seconds_policy,
                                                  report_.seconds_conversion, report_.seconds_bridge_mpi});
  if (!world_) return;
  world_->save_state(a, p + "rigid/");
  m.contact.save_state(a, p + "contact/");
  m.bonds.save_state(a, p + "bonds/");
  a.put_value(p + "since_rigid", m.since_rigid);
  a.put_value(p + "bonds_broken_synced", m.bonds_broken_synced);
  a.put(p + "ids", m.ids);
  a.put(p + "unconvertible", m.unconvertible);
  a.put(p + "u_filtered", m.u_filtered);
  a.put(p + "ref", m.ref);
  a.put_value(p + "t_ref", m.t_ref);
  a.put(p + "coupler_linear", m.coupler.linear());
  a.put(p + "coupler_angular", m.coupler.angular());
  // (RelaxReport goes in as bytes: a checkpoint of another layout is refused by its size)
  static_assert(std::is_trivially_copyable_v<RelaxReport>);
  if (m.relax.ran) {  // the relaxed world, for restore_relaxation (relax.cpp)
    a.put_value(p + "relax_report", m.relax);
    for (const auto& [key, value] : m.relaxed_world.entries) a.put_bytes(p + "relaxed/" + key, value);
    for (const auto& [key, value] : m.unjointed_world.entries) a.put_bytes(p + "unjointed/" + key, value);
    for (const auto& [key, value] : m.preconvert_world.entries) a.put_bytes(p + "preconvert/" + key, value);
    for (const auto& [key, value] : m.preconvert_engine.entries) a.put_bytes(p + "preconvert_engine/" + key, value);
  }
}

std::size_t HybridSystem::load_state(const StateArchive& a, const std::string& p) {
  Impl& m = *impl_;
  set_report_counts(report_, a.get<std::uint64_t>(p + "report_counts"));
  a.get_into(p + "report_by_criterion", report_.conversions_by_criterion);
  const auto rd = a.get<double>(p + "report_doubles");
  if (rd.size() != 5) throw std::runtime_error("hybrid checkpoint: report figures of another version");
  report_.max_utilisation = rd[0];
  report_.seconds_rigid = rd[1];
  report_.seconds_bonded = rd[2];
  report_.seconds_bridge = rd[3];
  report_.kinetic_energy_change = rd[4];
  if (a.has(p + "report_seconds")) {  // (a checkpoint without them restarts with them at zero)
    const auto rs = a.get<double>(p + "report_seconds");
    if (rs.size() != 6) throw std::runtime_error("hybrid checkpoint: report wall times of another version");
    double* dst[6] = {&report_.seconds_bonded_force, &report_.seconds_bonded_mpi, &report_.seconds_stress,
                      &report_.seconds_policy,       &report_.seconds_conversion, &report_.seconds_bridge_mpi};
    for (int k = 0; k < 6; ++k) *dst[k] = rs[static_cast<std::size_t>(k)];
  }
  if (!world_) {
    if (a.has(p + "rigid/blocks")) throw std::runtime_error("hybrid checkpoint: it has rigid blocks, the scene none");
    return 0;
  }
  const std::size_t lost = world_->load_state(a, p + "rigid/");
  m.contact.load_state(a, p + "contact/");
  m.bonds.load_state(a, p + "bonds/");
  m.since_rigid = a.get_value<std::uint64_t>(p + "since_rigid");
  m.bonds_broken_synced = a.get_value<std::uint64_t>(p + "bonds_broken_synced");
  a.get_into(p + "ids", m.ids);
  a.get_into(p + "unconvertible", m.unconvertible);
  a.get_into(p + "u_filtered", m.u_filtered);
  a.get_into(p + "ref", m.ref);
  m.t_ref = a.get_value<double>(p + "t_ref");
  m.frozen.assign(m.ref.size(), 0);
  if (!(m.ids == world_->blocks()) || m.ref.size() != m.ids.size() || m.contact.size() != m.ids.size())
    throw std::runtime_error("hybrid checkpoint: the blocks of the checkpoint and of the restored world differ");
  m.coupler.reset(world_->blocks());
  const auto cl = a.get<Vec3>(p + "coupler_linear"), ca = a.get<Vec3>(p + "coupler_angular");
  for (std::size_t k = 0; k < cl.size() && k < m.ids.size(); ++k)
    if (!cl[k].isZero(0.0) || !ca[k].isZero(0.0))
      throw std::runtime_error("hybrid checkpoint: impulses pending in the coupler (saved mid rigid step)");
  return lost;
}

void BlockContact::load_state_union(const std::vector<StateArchive>& all, const std::string& p, bool keep_sums) {
  load_state(all.at(0), p);
  for (auto& L : loads_) L = BlockLoad{};
  for (const StateArchive& a : all) {
    if (keep_sums) {
      const auto loads = a.get<BlockLoad>(p + "loads");
      if (loads.size() != loads_.size()) throw std::runtime_error("block contact checkpoint: ranks disagree");
      for (std::size_t k = 0; k < loads.size(); ++k) {
        loads_[k].force += loads[k].force;
        loads_[k].torque += loads[k].torque;
        loads_[k].impulse += loads[k].impulse;
        loads_[k].angular_impulse += loads[k].angular_impulse;
        loads_[k].contacts += loads[k].contacts;
      }
    }
    for (const auto& r : a.get<ContactHistoryRecord>(p + "history")) history_.emplace(Key{r.gid, r.block}, r.xi);
  }
}

void BlockParticleBonds::load_state_union(const std::vector<StateArchive>& all, const std::string& p,
                                          bool keep_sums) {
  load_state(all.at(0), p);
  cached_index_.assign(cached_index_.size(), bonded::ParticleStore::kNone);
  std::fill(impulse_.begin(), impulse_.end(), Vec3::Zero());
  std::fill(angular_impulse_.begin(), angular_impulse_.end(), Vec3::Zero());
  stats_ = BlockBondStats{};
  for (const StateArchive& a : all) {
    const auto bonds = a.get<BlockBondRecord>(p + "bonds");
    if (bonds.size() != bonds_.size()) throw std::runtime_error("block bond checkpoint: ranks disagree");
    for (std::size_t k = 0; k < bonds.size(); ++k) bonds_[k].broken = bonds_[k].broken || bonds[k].broken != 0;
    if (!keep_sums) continue;
    const auto imp = a.get<Vec3>(p + "impulse"), ang = a.get<Vec3>(p + "angular_impulse");
    for (std::size_t k = 0; k < imp.size() && k < impulse_.size(); ++k) {
      impulse_[k] += imp[k];
      angular_impulse_[k] += ang[k];
    }
    const auto st = a.get_value<BlockBondStats>(p + "stats");
    stats_.broken += st.broken;
    stats_.broken_tension += st.broken_tension;
    stats_.broken_shear += st.broken_shear;
  }
}

std::size_t HybridSystem::load_state_union(const std::vector<StateArchive>& all, const std::string& p) {
  Impl& m = *impl_;
  const StateArchive& a0 = all.at(0);
  if (!world_) return load_state(a0, p);
  // Everything but the rank-local parts as on rank 0, then those merged.
  const std::size_t lost = load_state(a0, p);
  const bool root = engine_.comm().rank() == 0;
  m.contact.load_state_union(all, p + "contact/", root);
  m.bonds.load_state_union(all, p + "bonds/", root);
  return lost;
}

}  // namespace hs::bridge

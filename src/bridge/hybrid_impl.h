// HybridSystem's private state (hybrid.cpp), in a header so that the checkpoint code
// (hybrid_state.cpp) can save and restore it. Not for other users.
#pragma once

#include "bridge/block_bonds.h"
#include "bridge/block_contact.h"
#include "bridge/coupling.h"
#include "bridge/hybrid.h"
#include "common/state_archive.h"

#include <vector>

namespace hs::bridge {

/// Whether a sphere of radius r at `site` reaches block o: its centre inside the box or closer
/// than r to its surface.
bool sphere_reaches_block(const rigid::RigidWorld& w, rigid::BlockId o, const Vec3& site, double r);
/// Block `id` of the world as the converter takes it.
BlockState block_state(const rigid::RigidWorld& w, rigid::BlockId id);

struct HybridSystem::Impl {
  HybridDef def;
  int mesh = -1;
  std::uint64_t since_rigid = 0;  ///< DEM steps since the last rigid step
  ImpulseCoupler coupler;
  std::vector<Vec3> no_parts;
  // Particle-block contact. Block k of `contact` is world block ids[k]; `ids` is always the
  // world's block list (slot order), which is also the coupler's order.
  BlockContact contact;
  BlockParticleBonds bonds;  ///< block-particle freeze bonds, block number = world slot index
  bool contact_registered = false;
  std::vector<Vec3> bond_lin, bond_ang;
  std::uint64_t bonds_broken_synced = 0;
  std::vector<rigid::BlockId> ids;
  std::vector<char> unconvertible;  ///< per world slot: the converter refused this block once
  std::vector<double> u_filtered;   ///< per world slot: low-pass filtered utilisation
  struct Ref {
    Vec3 x, v, w;
    Quat q;
  };
  std::vector<Ref> ref;  ///< block states at the last rigid step (time t_ref)
  double t_ref = 0.0;
  // The freeze that waits for the relaxation (HybridDef::defer_freeze): the joints as given,
  // the blocks' ids (BlockInit order) and their poses when the joints' anchors were given.
  bool freeze_pending = false;
  std::vector<JointInit> pending_joints;
  std::vector<IceJointInit> pending_ice_joints;
  std::vector<rigid::BlockId> pending_ids;
  std::vector<Vec3> x0;
  std::vector<Quat> q0;
  // all_at_start with a relaxation (convert_before_relaxation, relax.cpp): every block converted
  // before it, and the freeze couplings that the conversion made from the joints held back until
  // the freeze, which makes them again stress free.
  bool converted_before_relax = false;
  /// Per world slot, while the lattice stage converts every block at once (RelaxDef::lattice_time;
  /// empty otherwise): 1 for the blocks that stay rigid (plan_lattice_batch). A converted
  /// block's sites are then tested against those blocks' boxes and against the particles of the
  /// blocks converted before it, not against the boxes of the blocks still to come
  /// (docs/bridge.md, "Converting after a rigid relaxation").
  std::vector<char> batch_rigid;
  std::vector<bonded::Bond> held_bonds;             ///< particle-particle freeze bonds
  std::vector<BlockParticleBond> held_block_bonds;  ///< block-particle freeze bonds
  StateArchive relaxed_world;  ///< the rigid world at the end of the relaxation (checkpoints)
  /// The rigid world when the jointed stage began (its joints are made from these poses again
  /// when a checkpoint restores the relaxation).
  StateArchive unjointed_world;
  /// The rigid world the lattice stage converted (RelaxDef::lattice_time): a restart converts it
  /// again against preconvert_engine.
  StateArchive preconvert_world;
  /// The engine (the relaxed sheet) that conversion met, for the same restart.
  StateArchive preconvert_engine;
  RelaxReport relax;
  /// Per block k: 1 when ref[k] has v = w = 0 and the contact and bonds already hold its pose
  /// (extrapolation would set the same values again); cleared whenever ref[k] may change.
  std::vector<char> frozen;
  double wake_reach = 0.0;  ///< far sleep: largest block half diagonal (the region's wake box margin)

  /// Reads every block's state from the world as the new kinematic reference. A block that sleeps
  /// (far sleep) and was frozen already has that reference: its pose is unchanged and v = w = 0.
  void take_reference(const rigid::RigidWorld& w) {
    ref.resize(ids.size());
    frozen.resize(ids.size(), 0);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      if (frozen[k] && w.asleep(ids[k])) continue;
      ref[k] = {w.position(ids[k]), w.velocity(ids[k]), w.angular_velocity(ids[k]), w.orientation(ids[k])};
      frozen[k] = 0;
    }
    t_ref = w.time();
  }
  /// Moves the blocks the particles see to time t: x = x_r + v (t - t_r), q = exp(w (t - t_r)) q_r.
  /// (A block at rest in its reference gets the same values every time: set once, then skipped.)
  void extrapolate(double t) {
    const double tau = t - t_ref;
    frozen.resize(ids.size(), 0);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const Ref& r = ref[k];
      if (frozen[k]) continue;
      frozen[k] = r.v.isZero(0.0) && r.w.isZero(0.0);
      Quat q = r.q;
      const double angle = r.w.norm() * tau;
      if (angle > 0.0) q = (Quat(Eigen::AngleAxisd(angle, r.w.normalized())) * r.q).normalized();
      contact.set_state(k, r.x + tau * r.v, q, r.v, r.w);
      bonds.set_block(ids[k].index, BlockBody{r.x + tau * r.v, q, r.v, r.w, contact.block(k).half_extents});
    }
  }
};

}  // namespace hs::bridge

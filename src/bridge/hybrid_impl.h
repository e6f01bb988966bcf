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
  StateArchive relaxed_world;  ///< the rigid world at the end of the relaxation (checkpoints)
  RelaxReport relax;

  /// Reads every block's state from the world as the new kinematic reference.
  void take_reference(const rigid::RigidWorld& w) {
    ref.resize(ids.size());
    for (std::size_t k = 0; k < ids.size(); ++k)
      ref[k] = {w.position(ids[k]), w.velocity(ids[k]), w.angular_velocity(ids[k]), w.orientation(ids[k])};
    t_ref = w.time();
  }
  /// Moves the blocks the particles see to time t: x = x_r + v (t - t_r), q = exp(w (t - t_r)) q_r.
  void extrapolate(double t) {
    const double tau = t - t_ref;
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const Ref& r = ref[k];
      Quat q = r.q;
      const double angle = r.w.norm() * tau;
      if (angle > 0.0) q = (Quat(Eigen::AngleAxisd(angle, r.w.normalized())) * r.q).normalized();
      contact.set_state(k, r.x + tau * r.v, q, r.v, r.w);
      bonds.set_block(ids[k].index, BlockBody{r.x + tau * r.v, q, r.v, r.w, contact.block(k).half_extents});
    }
  }
};

}  // namespace hs::bridge

// The rigid-block world: ice blocks as Bullet rigid boxes (double precision) with
// gravity, exact box buoyancy, drag on the submerged part, block–block contact with
// friction, and breakable freeze joints. Bullet stays behind a pimpl: no bt* type here.
//
// Step (one call of step(), sub-stepped at def.dt):
//   1. water load (box_water.h (4)-(6)) and the caller's external forces/impulses are
//      applied to every dynamic block; kinematic meshes move to their pose at the end
//      of the sub-step (Bullet takes their velocity from that displacement);
//   2. Bullet integrates one fixed step (semi-implicit Euler + sequential-impulse
//      contacts, friction and joints);
//   3. every intact freeze joint reads the force it applied (btJointFeedback, impulse/dt),
//      splits it into normal (tension > 0) and shear parts relative to its normal and
//      breaks when  tension/A > sigma_t  or  |shear|/A > tau_s;
//   4. the contact impulses on every kinematic mesh are summed into its MeshLoad.
// Units: SI (m, kg, s, N, Pa).
#pragma once

#include "common/types.h"

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace hs {
class StateArchive;
}

namespace hs::rigid {

/// Handle to a block: slot index + generation (stale handles are detected).
struct BlockId {
  std::uint32_t index = UINT32_MAX;
  std::uint32_t generation = 0;
  bool valid() const { return index != UINT32_MAX; }
  friend bool operator==(const BlockId&, const BlockId&) = default;
};

/// Handle to a freeze joint: slot index + generation.
struct JointId {
  std::uint32_t index = UINT32_MAX;
  std::uint32_t generation = 0;
  bool valid() const { return index != UINT32_MAX; }
  friend bool operator==(const JointId&, const JointId&) = default;
};

struct RigidWorldDef {
  Vec3 gravity{0.0, 0.0, -9.81};    ///< m/s^2
  double dt = 1.0 / 240.0;          ///< fixed rigid sub-step, s
  int solver_iterations = 20;       ///< sequential-impulse iterations per step, at most
  /// Early exit of the sequential-impulse iterations, m/s: a solve stops after the first
  /// iteration in which no row changed its relative velocity by more than this (Bullet's
  /// m_leastSquaresResidualThreshold = tolerance^2: its residual is the largest squared velocity
  /// correction of a row in the iteration), and after `solver_iterations` at the latest. The same
  /// test ends the split-impulse (position) iterations. 0: every solve takes `solver_iterations`
  /// (docs/rigid.md, "Solver iterations and their early exit").
  double solver_tolerance = 0.0;

  // Water (ignored when water = false: no buoyancy, no drag).
  bool water = true;
  double water_level = 0.0;         ///< z of the still water surface, m
  double water_density = 1025.0;    ///< kg/m^3
  /// Linear face-normal drag c_lin, Pa s/m (N s/m per m^2 of wetted face). It is the
  /// heave damper: zeta_heave = c_lin / (2 sqrt(rho_w g rho_i h)) for a slab of
  /// thickness h (0.22 for h = 0.6 m at the default).
  double linear_drag = 1000.0;
  double quadratic_drag_cd = 1.0;   ///< C_d on leading wetted faces
  Vec3 water_current = Vec3::Zero(); ///< m/s (still water by default)

  // Contact.
  double friction = 0.3;            ///< ice–ice Coulomb coefficient
  double restitution = 0.0;
  /// Upper bound of the Bullet collision margin, m. The margin of a block is
  /// min(collision_margin, 0.2 * smallest half extent), i.e. 0.02 m for a 0.2 m thick
  /// block. btBoxShape keeps the margin inside its half extents, and box–box pairs use
  /// the exact-box algorithm, so the margin never inflates a block.
  double collision_margin = 0.02;
  /// Friction directions of a contact point. false (Bullet's default): one direction per
  /// point, along the current relative sliding velocity, recomputed every step. true: two
  /// fixed directions per point (a basis of the contact plane), kept for the point's
  /// lifetime, so the friction impulses are warm-started along the same directions from
  /// step to step (SOLVER_USE_2_FRICTION_DIRECTIONS | SOLVER_ENABLE_FRICTION_DIRECTION_CACHING
  /// | SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION). With false, static friction in a
  /// stack lets blocks creep at a few cm/s (docs/ridge.md); ~1/3 more solver rows.
  bool fixed_friction_directions = false;
  /// Friction rows that see the external torques (the water's, add_force's): true corrects
  /// Bullet's friction rows, which ignore them (PooledSolver::convertContacts says why); false,
  /// for now the default until the ridge set-up has been checked with it, keeps Bullet's rows
  /// (docs/rigid.md, "External torques and friction").
  bool friction_sees_torque = false;
  /// Error reduction (Baumgarte) of contacts and of joints, the fraction of a penetration or
  /// joint drift removed per step by a velocity correction; <= 0 keeps Bullet's 0.2. That
  /// correction velocity is erp x error / dt: at a small dt (the hybrid's rigid step, ~1e-3 s)
  /// Bullet's 0.2 turns a 3 cm overlap into 4 m/s of push and tears the freeze joints of a
  /// generated ridge apart; the hybrid scales erp with dt (docs/bridge.md).
  double contact_erp = -1.0;
  double joint_erp = -1.0;
  /// Penetrations deeper than this (m) are removed by Bullet's split impulse: a position
  /// correction that adds no momentum or kinetic energy; shallower ones by the erp velocity
  /// push, which does. Bullet's default 0.04 m; 0 = every penetration by split impulse.
  double split_impulse_depth = 0.04;

  // Freeze joints.
  double freeze_bond_strength = 50e3;        ///< tensile strength sigma_t, Pa
  double freeze_bond_shear_strength = -1.0;  ///< tau_s, Pa; < 0 means = sigma_t
  /// Joint compliance. 0: a joint is rigid (btFixedConstraint), its load whatever the solver's
  /// impulses make it, drift corrections (joint_erp) included. > 0: a joint is a spring over
  /// its patch, normal and shear stiffness `joint_stiffness` x area (N/m; the stiffness is per
  /// unit patch area, Pa/m), bending and twisting stiffness the same times the disc patch's
  /// second moment I = area^2 / (4 pi) and polar moment 2 I (N m/rad), each damped with
  /// ratio `joint_damping_ratio` (of the two blocks' reduced mass or inertia), and its load is
  /// the spring-damper force: determined by the deformation, not by the solver's drift
  /// corrections (docs/rigid.md, "Freeze joints"). Bullet keeps each spring below a quarter of
  /// its sampling rate (k <= m / (16 dt^2)), softening it at large steps.
  double joint_stiffness = 0.0;
  double joint_damping_ratio = 0.5;

  /// Allow Bullet to put resting blocks to sleep (off: floating blocks must respond
  /// to the water at every step, and sleeping hurts determinism across scenes).
  bool allow_sleep = false;
  /// With allow_sleep: a body is a sleep candidate below these speeds (Bullet's
  /// defaults); an island sleeps when all its bodies stayed candidates for 2 s.
  double sleep_linear_velocity = 0.8;   ///< m/s
  double sleep_angular_velocity = 1.0;  ///< rad/s

  /// Far sleep (docs/rigid.md, "Far sleep"): blocks far from anything that moves are not stepped.
  /// The rule, evaluated at the start of every sub-step from the world's own (replicated) state, so
  /// that every rank and a restarted run make the same decisions:
  ///   a block is kept awake while its centre lies within `wake_distance` of a kinematic mesh's
  ///   bounding box or inside a caller's wake box (set_wake_boxes), or the caller has loaded it
  ///   (add_force / add_impulse / set_velocity); a sleeping block wakes when a block it touches
  ///   (a contact point) or is jointed to, up to `wake_hops` contacts or joints away, moves faster
  ///   than `speed` or is loaded by the caller; an awake block falls asleep when no such block is
  ///   within `wake_hops` and it stayed slower than `speed` for `still_time`.
  /// Moving: |v| > speed or |w| |half extents| > speed. A sleeping block keeps its pose, has zero
  /// velocity, gets no gravity or water load, and meets awake blocks as an immovable one.
  /// Off (the default): every block is stepped at every sub-step, as Bullet's DISABLE_DEACTIVATION.
  /// Exclusive with allow_sleep (Bullet's own island sleeping).
  struct FarSleep {
    bool enabled = false;
    double wake_distance = 2.0;  ///< m
    double speed = 0.01;         ///< m/s
    double still_time = 0.5;     ///< s
    /// Blocks within this many contacts or joints of a moving (or caller-loaded) block are woken.
    int wake_hops = 4;
    /// Blocks start asleep (as if still for still_time already) unless the rule wakes them at the
    /// first sub-step: for a ridge at rest as generated, whose far part should not be stepped at all.
    bool start_asleep = false;
    /// A block the caller loads (the particles) is awake; with this it also seeds the wake_hops
    /// search as a moving block does. Off: only when it moves; a load it passes on to a sleeping
    /// neighbour reaches it through the solve (a sleeping block is held against its steady load and
    /// wakes when the load changes, docs/rigid.md "Far sleep"), so the sheet's steady loads on a
    /// ridge at rest keep only the blocks they touch awake.
    bool loads_wake_neighbours = false;
    /// A sleeping block the caller loads stays asleep: the caller's impulse over the sub-step
    /// (add_impulse, add_force x dt) counts in its load beside its contacts' and joints', and it
    /// wakes when that sum departs from its reference as a contact's load would (check_sleepers:
    /// |dJ| / m > speed per sub-step); an awake block the caller loads falls asleep when it is still.
    /// Off: a block the caller loads is awake (the rule above). docs/rigid.md, "Far sleep".
    bool loads_held = false;
    /// Read by the hybrid (bridge::HybridSystem), which owns the conversion region: the blocks of the
    /// region grown by the largest block and wake_distance are kept awake (a wake box), so that the
    /// conversion policy reads loads the solve gave them this sub-step. Off: those blocks sleep by
    /// the rule above like any other, and the policy reads a sleeping block's contacts and joints
    /// with other sleeping blocks as their last solve left them.
    bool region_awake = true;
    /// A block in the wake zone of a mesh (or a caller's wake box) also wakes the blocks within
    /// wake_hops, as a moving block does. Off: it keeps only itself awake until it moves; what the
    /// mesh pushes into it reaches a sleeping neighbour through the solve (check_sleepers).
    bool zone_wakes_neighbours = true;
  } far_sleep;
};

struct BlockDef {
  Vec3 half_extents{0.5, 0.5, 0.5};  ///< m
  Vec3 position = Vec3::Zero();      ///< centre, m
  Quat orientation = Quat::Identity();
  Vec3 velocity = Vec3::Zero();      ///< m/s
  Vec3 angular_velocity = Vec3::Zero();  ///< rad/s, world
  double density = 910.0;            ///< kg/m^3
  bool fixed = false;                ///< static block (floor, wall); no water load
  double friction = -1.0;            ///< < 0: RigidWorldDef::friction
  /// Per-axis factors (world frame) on the velocity changes of this block (Bullet's
  /// linear/angular factor): (0, 0, 1) and 0 make a body that only heaves (the ridge
  /// generator's floating plates). Not part of the checkpoint: worlds that restore
  /// (the run's) use the defaults.
  Vec3 linear_factor = Vec3::Ones();
  Vec3 angular_factor = Vec3::Ones();
};

/// A freeze joint between two touching blocks at `anchor` (world point on the common
/// face), with `normal` (world unit vector, pointing from a to b) and bonded `area` m^2.
struct FreezeJointDef {
  BlockId a, b;
  Vec3 anchor = Vec3::Zero();
  Vec3 normal{0.0, 0.0, 1.0};
  double area = 1.0;
};

/// A kinematic triangle mesh (the structure): it moves at a prescribed constant
/// velocity, pushes blocks and is never pushed back. Plain arrays, so that the rigid
/// module needs no mesh library; the caller passes a hs::mesh::TriMesh's arrays.
struct KinematicMeshDef {
  std::vector<Vec3> vertices;                            ///< in the mesh frame, m
  std::vector<std::array<std::uint32_t, 3>> triangles;   ///< CCW seen from outside
  std::vector<std::uint16_t> triangle_part;              ///< part of each triangle; empty = all 0
  std::size_t part_count = 1;
  Vec3 position = Vec3::Zero();  ///< world position of the mesh frame origin at t = 0, m
  Vec3 velocity = Vec3::Zero();  ///< m/s
  /// Block–structure Coulomb coefficient, used as is for every block (not combined
  /// with the block's own coefficient).
  double friction = 0.1;
};

/// Load exerted BY the blocks ON a kinematic mesh during the last sub-step: the contact
/// impulses (normal and friction) that Bullet's solver applied, divided by the sub-step.
struct MeshLoad {
  Vec3 force = Vec3::Zero();              ///< N
  Vec3 moment = Vec3::Zero();             ///< N m, about the mesh frame origin
  std::vector<Vec3> part_force, part_moment;
  std::size_t contacts = 0;               ///< contact points that carried an impulse
};

/// Last measured load of a joint (force on b from the joint, split along the normal).
struct JointLoad {
  double tension = 0.0;  ///< N, > 0 pulls b towards a
  double shear = 0.0;    ///< N, magnitude of the tangential part
};

class RigidWorld {
 public:
  explicit RigidWorld(const RigidWorldDef& def = {});
  ~RigidWorld();
  RigidWorld(const RigidWorld&) = delete;
  RigidWorld& operator=(const RigidWorld&) = delete;

  const RigidWorldDef& def() const;

  BlockId add_block(const BlockDef& b);
  /// Removes a block and its joints; its id becomes stale.
  void remove_block(BlockId id);
  bool alive(BlockId id) const;
  std::size_t block_count() const;
  /// Alive blocks in slot order (deterministic).
  std::vector<BlockId> blocks() const;

  /// Advances by `duration` in whole sub-steps of def.dt (at least one).
  void step(double duration);
  /// Advances by exactly one sub-step of def.dt.
  void substep();
  double time() const;
  std::uint64_t step_count() const;
  /// Time and step count back to zero (the run's t = 0 after a set-up stage such as the
  /// ridge's relaxation); every body, joint and contact is kept.
  void reset_clock();

  Vec3 position(BlockId id) const;
  Quat orientation(BlockId id) const;
  Vec3 velocity(BlockId id) const;
  Vec3 angular_velocity(BlockId id) const;
  Vec3 half_extents(BlockId id) const;
  double mass(BlockId id) const;  ///< 0 for fixed blocks
  bool fixed(BlockId id) const;
  void set_velocity(BlockId id, const Vec3& v, const Vec3& w);
  void set_pose(BlockId id, const Vec3& x, const Quat& q);
  /// Coulomb coefficient of a block (fixed ones too); two blocks meet with the product
  /// of their square roots, as in add_block. Takes effect from the next sub-step.
  void set_friction(BlockId id, double mu);
  /// Sequential-impulse iterations from the next sub-step on (>= 1).
  void set_solver_iterations(int n);
  /// The solver's work since the world was made: solves (one per sub-step, and one per repeat
  /// under far sleep), the velocity iterations they took in all, and the most one took.
  struct SolverStats {
    std::uint64_t solves = 0, iterations = 0;
    int max_iterations = 0;
    double mean_iterations() const { return solves ? static_cast<double>(iterations) / solves : 0.0; }
  };
  SolverStats solver_stats() const;

  /// External force (N) at a world point, applied during every following sub-step
  /// until clear_external_forces(); for loads held over a rigid step.
  void add_force(BlockId id, const Vec3& f, const Vec3& point);
  void clear_external_forces();
  /// Impulse (N s) at a world point, applied once at the start of the next sub-step
  /// (the bridge pours accumulated particle impulses in here).
  void add_impulse(BlockId id, const Vec3& j, const Vec3& point);

  /// Far sleep (RigidWorldDef::far_sleep): boxes (lo, hi corners, world) whose blocks (by centre)
  /// never sleep, e.g. the conversion region; replaces the previous set. Used from the next sub-step.
  void set_wake_boxes(const std::vector<std::pair<Vec3, Vec3>>& boxes);
  /// True while block `id` sleeps (far sleep; never without it).
  bool asleep(BlockId id) const;
  /// Dynamic blocks awake now (all dynamic blocks without far sleep).
  std::size_t awake_count() const;
  /// Awake dynamic blocks moving by the far-sleep rule (|v| or |w| |h| above far_sleep.speed).
  std::size_t moving_count() const;
  /// Far sleep: sleeping blocks woken by a change of the load a solve gave them (a hit or a pull;
  /// each made the world solve its sub-step again, unless the sub-step's repeats were used up),
  /// since the world was made.
  std::size_t sleepers_woken_by_solve() const;
  /// Far sleep: sub-step solves done again because a solve woke sleeping blocks.
  std::size_t solves_repeated() const;
  /// Dynamic blocks stepped (integrated by the solver), summed over the sub-steps since the world was
  /// made: every dynamic block at every sub-step without far sleep; with it the awake ones, and those
  /// a solve woke once more in the sub-step's repeated solve. What sleeping saves, counted.
  std::uint64_t stepped_body_count() const;

  /// Sum of 1/2 m v^2 + 1/2 w.I w over dynamic blocks, J.
  double kinetic_energy() const;

  /// Adds a kinematic mesh (see KinematicMeshDef); returns its index. Throws
  /// hs::InputError for an empty mesh or an index out of range.
  int add_kinematic_mesh(const KinematicMeshDef& def);
  std::size_t kinematic_mesh_count() const;
  /// World position of mesh k's frame origin now.
  Vec3 mesh_position(int k) const;
  /// Load of the blocks on mesh k during the last sub-step.
  const MeshLoad& mesh_load(int k) const;

  /// A contact force that acted on a block during the last sub-step (from another block or a
  /// kinematic mesh): Bullet's normal + friction impulse at the point, divided by the sub-step.
  struct ContactForce {
    Vec3 point = Vec3::Zero();  ///< world, on the block's surface, m
    Vec3 force = Vec3::Zero();  ///< on the block, N
  };
  /// Every contact force on block `id` in the last sub-step (walks all contact manifolds).
  std::vector<ContactForce> contact_forces(BlockId id) const;
  /// Intact freeze joints that hold block `id`, in slot order.
  std::vector<JointId> joints_of(BlockId id) const;
  double joint_area(JointId id) const;
  /// A joint's blocks, and its anchor and normal (a -> b) carried along with block a, now.
  FreezeJointDef joint_def(JointId id) const;

  JointId add_freeze_joint(const FreezeJointDef& j);
  /// How far an intact joint's two frames (fixed in a and in b, coincident when it was made)
  /// are apart now: translation (m) and rotation angle (rad). Zero at creation: a joint is made
  /// stress free in the current poses.
  struct JointStrain {
    double displacement = 0.0, angle = 0.0;
  };
  JointStrain joint_strain(JointId id) const;
  void remove_joint(JointId id);
  bool joint_broken(JointId id) const;
  JointLoad joint_load(JointId id) const;
  /// Freeze joints broken since the world was made.
  std::size_t broken_joint_count() const;
  std::size_t joint_count() const;  ///< intact joints
  /// false: joints hold whatever their load (it is still measured); the relaxation's jointed
  /// stage (bridge::RelaxDef::jointed_time). Not saved in checkpoints (true after a freeze).
  void set_joints_breakable(bool on);
  /// Intact joints whose last load exceeds their strength (they break at the next check when
  /// breakable).
  std::size_t overloaded_joint_count() const;

  // ---- checkpoint (docs/output.md, "Checkpoints"; world_state.cpp) ----
  /// Saves everything a later sub-step reads, under keys prefix + "...": per block slot its
  /// liveness, generation, Bullet transform, interpolation transform, velocities, activation
  /// state, deactivation time, hit fraction, friction and pending external loads; per joint slot
  /// its liveness, broken flag and last load; the kinematic meshes' poses and loads; every contact
  /// manifold (keyed by its two bodies) with every field of every contact point; time and steps.
  void save_state(StateArchive& a, const std::string& prefix) const;
  /// Restores a world built exactly as the saved one was built (same blocks, joints and meshes
  /// added in the same order; blocks removed since are removed here): bodies and joints take the
  /// saved state, one collision detection pass creates the pairs and manifolds, then each
  /// manifold's points are replaced by the saved ones (manifolds not saved are emptied). Returns
  /// the number of saved contact points whose manifold did not reappear (0 in every case
  /// measured; each such point would be a deviation from the original run).
  std::size_t load_state(const StateArchive& a, const std::string& prefix);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hs::rigid

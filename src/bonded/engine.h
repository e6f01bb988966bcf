// The bonded-particle DEM engine: owns the particle store, bonds, contact pairs and
// walls, and advances them with velocity Verlet.
//
// One step (data flows one way):
//   1. half kick     v += dt/2 F/m,  w += dt/2 T/I        (forces of the last step)
//   2. drift         x += dt v,  q = exp(w dt) q          (track the Verlet-skin motion)
//   3. neighbours    rebuild the contact-pair list if a particle moved > skin/2
//   4. forces        fields (gravity, water) -> walls -> meshes -> force sources -> contact pairs -> bonds
//   5. half kick     with the new forces; blow-up check
// Loops run over the owned range [0, n_owned); pair and bond loops may touch ghosts.
//
// Bonds are the authority on bonding: the contact-pair list never holds a bonded pair.
// When a bond breaks its force is removed at once and the pair joins the contact list,
// so the two particles interact by contact from the next force evaluation on.
#pragma once

#include "bond_kernel.h"
#include "bond_parallel.h"
#include "bond_strength_spread.h"
#include "mesh/sphere_mesh_contact.h"
#include "contact_law.h"
#include "particle_store.h"
#include "wall.h"
#include "water.h"
#include "parallel/comm.h"
#include "parallel/decomposition.h"

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <unordered_map>
#include <string>
#include <vector>

namespace hs {
class StateArchive;
}

namespace hs::bonded {

enum class BondKind : std::uint8_t { Lattice = 0, Freeze = 1 };

/// Blow-up detection: the run stops with a diagnostic instead of writing garbage.
struct StabilityLimits {
  double max_speed = 100.0;         ///< m/s; ice never moves this fast
  double max_overlap_ratio = 0.5;   ///< contact overlap / smaller radius
};

struct EngineDef {
  double dt = 0.0;                   ///< s; 0 = paper Eq. 2 with dt_alpha
  double dt_alpha = 0.1;             ///< alpha in dt = alpha D sqrt(rho/E)
  double youngs_modulus = 1e9;       ///< E, Pa (for Eq. 2 and Hertz)
  double poisson_ratio = 0.3;
  double density = 920.0;            ///< rho of the particles' material, for Eq. 2
  Vec3 gravity{0.0, 0.0, -9.81};
  ContactModel contact_model = ContactModel::LinearSpringDashpot;  ///< the law (contact_law.h)
  LinearContactParams contact;       ///< particle-particle (linear law)
  HertzContactParams hertz;          ///< particle-particle (Hertz law)
  double hertz_reference_overlap = 0.02;  ///< overlap/radius used for Hertz stiffness in the dt check
  ParallelBondParams bond[2];        ///< indexed by BondKind
  WaterParams water;
  double skin = 0.0;                 ///< Verlet skin, m; 0 = 0.1 * smallest diameter
  bool spatial_sort = true;          ///< reorder particles by cell at neighbour rebuilds
  StabilityLimits limits;
  /// A bond that breaks with its particles deeper than crushed_set_depth x the smaller radius
  /// (squeezed, crushed) leaves its pair a contact with a permanent set: the overlap beyond that
  /// depth (docs/engine.md, "Crushed bonds"). false: the contact starts from the whole overlap.
  bool crushed_set = true;
  /// h, as a fraction of the smaller radius: half the default limits.max_overlap_ratio. Its own
  /// figure, not derived from the limit: a limit is a check, and changing it (on a restart, say)
  /// must not change the physics.
  double crushed_set_depth = 0.25;
  /// Scatter of the lattice bonds' strengths (bond_strength_spread.h): each lattice bond's
  /// strengths are bond[Lattice]'s times its factor Bond::strength. Spread 0: every factor is 1.
  BondStrengthSpread lattice_strength_spread;
};

/// What a force source sees of the force evaluation it takes part in.
struct ForceSourceContext {
  const EngineDef& def;   ///< the engine's definition (contact law and its parameters)
  double history_dt;      ///< s; tangential springs advance by v_t * history_dt (0 in compute_forces())
  double time;            ///< s; engine time of the state being evaluated
};

/// Overlap figure of a force source, for the engine's blow-up check.
struct ForceSourceResult {
  double worst_overlap_ratio = 0.0;  ///< largest overlap / particle radius among its contacts
  std::uint32_t worst_particle = 0;  ///< local index of that particle
};

/// Forces on particles from outside the particle world (e.g. rigid blocks, src/bridge), added
/// in every force evaluation after walls and meshes, so they take part in the Verlet step and
/// in the blow-up check. A source touches owned particles [0, n_owned) only (adding to ps.f and
/// ps.torque); under MPI each rank calls its own sources on its own particles, and any reaction
/// it tallies is that rank's share. It must not move tangential history when history_dt == 0.
class ForceSource {
 public:
  virtual ~ForceSource() = default;
  virtual ForceSourceResult add_forces(ParticleStore& ps, std::size_t n_owned, const ForceSourceContext& ctx) = 0;
  /// For diagnostics ("contact overlap ... between particle 12 and <name>").
  virtual const char* name() const { return "an external force source"; }
  /// For the blow-up message: the body on the source's side of its worst contact in the last
  /// add_forces() call, whose particle was local index i and moved at v_mid in this step (its
  /// mid-step velocity, which the step's forces saw) ("rigid block 17 at (...) moving at ...").
  /// The default is name().
  virtual std::string describe_worst(const ParticleStore& /*ps*/, std::uint32_t /*i*/, const Vec3& /*v_mid*/) const {
    return name();
  }
  /// MPI migration of per-particle state (e.g. tangential springs), so that it travels with its
  /// particle as the engine's own contact history does. pack_history: for every particle in
  /// `leaving` (global id -> destination rank) append its records to out[rank] (the source's own
  /// byte format) and forget them here. unpack_history: take records that pack_history wrote on
  /// another rank. Every rank must register the same sources in the same order. A source without
  /// per-particle state keeps the defaults (nothing travels).
  virtual void pack_history(const std::unordered_map<GlobalId, int>& /*leaving*/, std::vector<par::Bytes>& /*out*/) {}
  virtual void unpack_history(const char* /*data*/, std::size_t /*size*/) {}
  /// True when its forces depend on particle orientations (e.g. bonds to a block): the engine
  /// then integrates orientations even without particle-particle bonds.
  virtual bool uses_orientation() const { return false; }
};

/// How the engine spreads over MPI ranks (docs/parallel.md).
struct ParallelDef {
  std::array<int, 3> grid{0, 0, 0};      ///< boxes per axis; all 0 = choose (least cut area)
  std::uint64_t balance_interval = 500;  ///< steps between load-balance checks (at a neighbour rebuild); 0 = never
  enum class Cost { Work, Time };
  /// Work: per-particle cost counted from its contacts and bonds (deterministic; default).
  /// Time: the same, scaled per rank by its measured force-evaluation time (adapts to uneven
  /// hardware, but cut positions then vary from run to run, and so do the last bits of the results).
  Cost cost = Cost::Work;
  int histogram_bins = 1024;             ///< resolution of the cost histogram along each axis
};

/// Counters of the parallel machinery (zero in a serial run).
struct ParallelStats {
  std::uint64_t exchanges = 0;     ///< full exchanges (migration + new ghost lists), one per rebuild
  std::uint64_t migrated = 0;      ///< particles this rank sent to another
  std::uint64_t balances = 0;      ///< times the cuts were moved
  double comm_seconds = 0.0;       ///< wall time in ghost exchanges and reductions on this rank
  double force_seconds = 0.0;      ///< wall time in force evaluation on this rank (cost measure)
};

/// A pair of global ids in canonical order (a < b): the key of contact history.
struct GidPair {
  GlobalId a, b;
  static GidPair of(GlobalId x, GlobalId y) { return x < y ? GidPair{x, y} : GidPair{y, x}; }
  bool operator==(const GidPair& o) const { return a == o.a && b == o.b; }
};
struct GidPairHash {
  std::size_t operator()(const GidPair& k) const {
    return std::hash<std::uint64_t>()(k.a * 0x9E3779B97F4A7C15ull ^ (k.b + 0x632BE59BD9B4E019ull));
  }
};

/// The tangential spring of one particle-particle contact, named by the pair's global ids
/// (checkpoints, cached benchmark packs): how contact history is read and set from outside.
struct PairHistory {
  GlobalId a, b;  ///< a < b
  Vec3 xi;        ///< tangential spring: displacement of b's contact point relative to a's, m
};

struct Bond {
  std::uint32_t i, j;    ///< local indices (refreshed on reorder)
  GlobalId gi, gj;       ///< gi < gj: canonical order, so results do not depend on storage order
  BondKind kind;
  BondRef ref;
  /// Multiplies the kind's strengths sigma_c, tau_c, sigma_cc (EngineDef::lattice_strength_spread):
  /// a function of the ids, set wherever a bond is made (Engine::bond_strength), never stored.
  double strength = 1.0;
};

/// Scratch of the bond sort at a rebuild (engine.cpp, sort_bonds_by_particle), kept between
/// rebuilds so that the sort touches no fresh pages.
struct BondSortScratch {
  std::vector<std::uint32_t> start, fill, order, hi;
  std::vector<char> done;
};

/// Orders bonds by their particles' local indices (the lower, then the higher) for cache locality
/// at a rebuild. The order is a function of the positions only, so runs stay deterministic. A pair
/// has one bond, so the keys are unique: the order is the one any sort on (min, max) gives.
/// n_particles: greater than every bond's index (Engine passes ps_.size(), ghosts included).
void sort_bonds_by_particle(std::vector<Bond>& bonds, std::size_t n_particles, BondSortScratch& scratch);

struct ContactPair {
  std::uint32_t i, j;
  Vec3 xi;               ///< tangential spring history
};

/// A rigid triangle-mesh structure (e.g. the pier) moving at a prescribed velocity.
/// Contact with spheres uses the particle contact law over every face, edge and vertex
/// contact that hs::mesh::MeshGrid reports (no double counting); forces are tallied per
/// named part of the mesh.
struct MeshWallDef {
  std::string name = "structure";
  mesh::TriMesh mesh;               ///< in its own frame
  Vec3 position = Vec3::Zero();     ///< world position of the mesh frame origin, m
  Vec3 velocity = Vec3::Zero();     ///< m/s
  double friction = 0.1;            ///< ice-structure Coulomb friction
};

/// Loads on a mesh wall during the last step (exerted BY the particles ON the wall).
struct MeshWallLoad {
  Vec3 force = Vec3::Zero();                 ///< N
  Vec3 moment = Vec3::Zero();                ///< N m, about the mesh frame origin
  std::vector<Vec3> part_force, part_moment;  ///< per TriMesh part
  std::size_t contacts = 0;
};

/// A bonded lattice to add to an engine that may already be running (Engine::insert_lattice),
/// e.g. a rigid block turned into particles. Under MPI every rank passes the same one.
struct LatticeInsert {
  std::vector<ParticleInit> sites;
  std::vector<std::array<std::uint32_t, 2>> bonds;  ///< pairs of site indices, bonded stress free
  BondKind kind = BondKind::Lattice;
  /// A bond from a particle already in the engine to a site (stress free at insertion, like
  /// `bonds`; not made when its site is dropped): e.g. a converted block's freeze bonds to the
  /// particles it was frozen to.
  struct Attach {
    GlobalId particle = 0;
    std::uint32_t site = 0;
    BondKind kind = BondKind::Freeze;
  };
  std::vector<Attach> attach;
  /// Drop the sites that would start in contact overlap with existing particles
  /// (Engine::overlapping_sites), and their bonds.
  bool drop_overlapping = true;
  /// Appends a site.
  void add_site(const ParticleInit& p) { sites.push_back(p); }
};

/// What Engine::insert_lattice did: the same on every rank, figures over all ranks.
struct LatticeInsertReport {
  static constexpr GlobalId kDropped = ~GlobalId{0};
  std::vector<GlobalId> gid;  ///< per site: its global id, or kDropped
  GlobalId first_gid = 0;     ///< the kept sites have first_gid, first_gid + 1, ... in site order
  std::size_t particles_created = 0, particles_dropped = 0, bonds_created = 0;
  std::size_t attached = 0;   ///< bonds made from LatticeInsert::attach
};

/// Pairs (i, j), i < j, ascending, of the spheres (x, radius) whose centres lie within
/// (r_i + r_j)(1 + rel_tol) of each other: the bonds of a lattice of touching spheres.
std::vector<std::array<std::uint32_t, 2>> touching_pairs(const std::vector<Vec3>& x, const std::vector<double>& radius,
                                                         double rel_tol = 1e-6);

struct EnergyReport {
  double kinetic_translational = 0, kinetic_rotational = 0;
  double gravity_potential = 0, buoyancy_potential = 0;
  double bond_elastic = 0, contact_elastic = 0;
  double total() const {
    return kinetic_translational + kinetic_rotational + gravity_potential + buoyancy_potential +
           bond_elastic + contact_elastic;
  }
};

struct StepStats {
  std::uint64_t neighbor_rebuilds = 0;
  std::uint64_t bonds_broken = 0;        ///< since the start
  std::uint64_t bonds_broken_tension = 0;
  std::uint64_t bonds_broken_shear = 0;
  std::uint64_t bonds_broken_compression = 0;  ///< past ParallelBondParams::sigma_cc
};

class Engine {
 public:
  explicit Engine(const EngineDef& def);

  // ---- building the system ----
  std::size_t add_particle(const ParticleInit& p);
  /// Bond two particles (by global id) in their current configuration (stress free).
  void add_bond(GlobalId a, GlobalId b, BondKind kind = BondKind::Lattice);
  /// Removes every bond for which `which` is true and returns them, in list order; their pairs
  /// interact by contact from the next step (the neighbour lists are rebuilt). Serial only
  /// (before distribute(); std::logic_error otherwise). For a set-up stage that holds bonds back
  /// and makes them again with add_bond, stress free, afterwards (docs/bridge.md, "Relaxation").
  std::vector<Bond> remove_bonds(const std::function<bool(const Bond&)>& which);
  /// Bond every pair among particles [first, last) whose centres are within
  /// (r_i + r_j)(1 + rel_tol) of each other. Returns the number of bonds made.
  std::size_t bond_touching(std::size_t first, std::size_t last, BondKind kind,
                            double rel_tol = 1e-6);
  /// Per site (centre x[k], radius radius[k]): 1 when it lies closer than r_j + radius[k] to an
  /// existing particle j, i.e. would start in contact overlap (exactly touching is not overlap).
  /// Collective under MPI: each rank tests its owned particles, the masks are OR-reduced, every
  /// rank gets the same mask.
  std::vector<char> overlapping_sites(const std::vector<Vec3>& x, const std::vector<double>& radius) const;
  /// Adds a bonded lattice at any time, serial or distributed (collective under MPI: every rank
  /// passes the same `lat`). Kept sites get consecutive global ids in site order from a counter
  /// that every rank holds alike, so the ids do not depend on the rank count. Serial: the same as
  /// add_particle for each kept site, then add_bond in ascending id order. Under MPI each rank adds
  /// the kept sites in its box and the bonds whose lower-id site it owns, then makes new ghosts and
  /// binds every new bond by id (a partner out of reach throws SimulationError on every rank) and
  /// rebuilds the neighbour lists. `attach` bonds (existing particle -> site) live, like every
  /// bond, on the owner of the lower id, which is always the existing particle: its owner makes
  /// the bond from its own state and the site's. Throws std::invalid_argument (on every rank,
  /// nothing added) for a site without positive mass and radius, a bond out of range, to itself
  /// or listed twice, or an attach naming a particle the engine does not own (on any rank) or a
  /// site out of range.
  LatticeInsertReport insert_lattice(const LatticeInsert& lat);
  int add_wall(const PlaneWall& w);
  /// Adds a moving triangle-mesh wall; throws hs::InputError if the mesh is invalid.
  int add_mesh_wall(MeshWallDef def);
  /// Registers a force source (not owned; it must outlive its registration). Sources are called
  /// in the order added. Without any, force evaluation is unchanged.
  void add_force_source(ForceSource* source);
  void remove_force_source(ForceSource* source);

  // ---- time step ----
  /// dt from paper Eq. 2: alpha D sqrt(rho/E) with the smallest particle diameter.
  double eq2_time_step() const;
  /// Upper bound on the stable velocity-Verlet step: Gershgorin bound on the highest
  /// frequency of the stiffest springs (contacts, bond normal/shear/bending/twist,
  /// lever arms and coordination included), reduced for damping (docs/engine.md):
  /// dt_crit = (2/omega_max)(sqrt(1+zeta^2) - zeta).
  double critical_time_step() const;
  /// Throws hs::InputError naming the limit and the fix if dt > critical_time_step().
  void check_time_step() const;
  double dt() const { return dt_; }
  /// Fixes the time step (it no longer follows Eq. 2 as particles are added).
  void set_dt(double dt) {
    dt_ = dt;
    dt_auto_ = false;
  }

  // ---- running ----
  void step();
  void run(std::uint64_t steps);
  double time() const { return time_; }
  std::uint64_t step_count() const { return step_; }
  /// Set-up stages before a run's t = 0 (the ridge's relaxation, docs/bridge.md): while parked,
  /// plane and mesh walls do not move and mesh walls exert no force (plane walls still hold).
  void set_walls_parked(bool parked) {
    walls_parked_ = parked;
    forces_valid_ = false;
  }
  bool walls_parked() const { return walls_parked_; }
  /// Set-up stages (all_at_start's lattice stage, docs/bridge.md): bonds of `kind` cannot break
  /// while set (their strengths are taken as infinite; their forces are as always).
  void set_bonds_unbreakable(BondKind kind, bool unbreakable) { bonds_unbreakable_[static_cast<int>(kind)] = unbreakable; }
  bool bonds_unbreakable(BondKind kind) const { return bonds_unbreakable_[static_cast<int>(kind)]; }
  /// This rank's bonds of `kind`, and those of them whose stresses now exceed their strengths
  /// (meant for a serial engine, e.g. the relaxation before distribute(): under MPI a bond whose
  /// ends lie on two ranks may be counted on both).
  std::size_t bond_count(BondKind kind) const;
  std::size_t overloaded_bond_count(BondKind kind) const;
  /// Time and step count back to zero and the bond-break counters cleared: the run's t = 0
  /// after a set-up stage (the state of every particle and bond is kept).
  void reset_clock() {
    time_ = 0.0;
    step_ = 0;
    stats_ = StepStats{stats_.neighbor_rebuilds};
    squeezed_breaks_.clear();  // their step numbers were the set-up stage's
  }

  // ---- state and diagnostics ----
  ParticleStore& particles() { return ps_; }
  const ParticleStore& particles() const { return ps_; }
  const std::vector<Bond>& bonds() const { return bonds_; }
  /// Crushed pairs on this rank (EngineDef::crushed_set): their contact acts on the overlap
  /// beyond `set`; -1 if the pair has no set.
  std::size_t crushed_pair_count() const { return crushed_.size(); }
  double crushed_set_of(GlobalId a, GlobalId b) const;
  const std::vector<ContactPair>& contact_pairs() const { return pairs_; }
  const std::vector<PlaneWall>& walls() const { return walls_; }
  std::vector<PlaneWall>& walls() { return walls_; }
  /// Force exerted BY the particles ON wall k during the last step, N.
  const Vec3& wall_force(int k) const { return wall_force_[k]; }
  std::size_t mesh_wall_count() const { return meshes_.size(); }
  const MeshWallDef& mesh_wall(int k) const { return meshes_[k].def; }
  const MeshWallLoad& mesh_wall_load(int k) const { return meshes_[k].load; }
  /// Water exposure of owned particle i (water.h), as of the last neighbour rebuild.
  const ParticleExposure& exposure(std::size_t i) const { return exposure_[i]; }
  /// Current world position of mesh wall k's frame origin.
  const Vec3& mesh_wall_position(int k) const { return meshes_[k].position; }
  const StepStats& stats() const { return stats_; }
  /// Largest contact overlap / particle radius of the last force evaluation on this rank
  /// (particle pairs, walls, meshes, force sources): what stability.max_overlap_ratio limits.
  double worst_overlap_ratio() const { return worst_overlap_ratio_; }
  const EngineDef& def() const { return def_; }
  EngineDef& mutable_def() { return def_; }

  // ---- friction history by name (checkpoints, cached benchmark packs) ----
  /// The nonzero tangential springs of the contact pairs this rank computes, sorted by (a, b).
  std::vector<PairHistory> contact_history() const;
  /// Replaces the contact springs (pairs not listed start at zero). They are taken up by the
  /// next neighbour rebuild, which this forces. Under MPI each rank may pass them all.
  void set_contact_history(const std::vector<PairHistory>& h);
  /// Plane wall k's tangential spring on particle i (local index; owned particles).
  const Vec3& wall_history(int k, std::size_t i) const { return wall_hist_[k][i]; }
  void set_wall_history(int k, std::size_t i, const Vec3& xi) {
    wall_hist_[k][i] = xi;
    forces_valid_ = false;
  }

  EnergyReport energy() const;
  Vec3 linear_momentum() const;
  Vec3 angular_momentum(const Vec3& about = Vec3::Zero()) const;

  // ---- MPI ----
  /// Spreads a system that every rank built identically (same particles, ids and bonds) over the
  /// ranks of `comm`: each keeps the particles in its box, the bonds whose lower-id particle it
  /// owns, and ghost copies of its neighbours' particles within the interaction range. With a
  /// one-rank comm nothing changes. Collective: every rank calls it, and from then on every rank
  /// calls step(), energy(), momenta and the counts below together.
  void distribute(const par::Comm& comm, const ParallelDef& def = {});
  const par::Comm& comm() const { return *comm_; }
  bool parallel() const { return comm_->parallel(); }
  const par::Decomposition& decomposition() const { return dom_; }
  const ParallelStats& parallel_stats() const { return pstats_; }
  /// Totals over all ranks (collective).
  std::int64_t global_particle_count() const;
  std::int64_t global_bond_count() const;
  std::size_t ghost_count() const { return ps_.n_ghost; }
  /// Brings owned particles' bond counts up to date after bonds broke on other ranks (collective;
  /// also done at every neighbour rebuild). A no-op in a serial run.
  void refresh_bond_counts();

  /// Called after every step (for probes/output); optional.
  std::function<void(const Engine&)> on_step;

  // ---- checkpoint (engine_state.cpp; docs/output.md, "Checkpoints") ----
  /// Saves this rank's whole dynamic state under prefix + "...": every particle array (owned and
  /// ghosts, in store order), bonds with their reference states, contact pairs with their
  /// tangential springs (the neighbour list itself), wall and mesh friction history, the positions
  /// at the last neighbour rebuild, the forces of the last step, time, step, counters, and under
  /// MPI the cuts, ghost lists and balance schedule.
  void save_state(StateArchive& a, const std::string& prefix) const;
  /// Restores what save_state wrote into an engine built from the same scene (same walls, meshes
  /// and definitions) and, under MPI, distributed over the same number of ranks. The next step
  /// then computes exactly what the saved engine's next step would have.
  void load_state(const StateArchive& a, const std::string& prefix);
  /// Restores a checkpoint written at another rank count (`all`: every saved rank's archive):
  /// the union of the saved ranks' owned particles, bonds and friction history becomes one
  /// system, which this engine then spreads over its own ranks as distribute() does (collective;
  /// every rank passes the same `all`). The forces of the last step are carried by particle; the
  /// neighbour lists are rebuilt at the saved positions of the last rebuild (then the current
  /// positions restored), so later rebuilds, hence water-exposure updates, fall on the saved
  /// run's steps: the same physics to round-off, summed in another order (docs/output.md
  /// "Checkpoints").
  void load_state_union(const std::vector<StateArchive>& all, const std::string& prefix);

  /// Forces for the current state without advancing anything: tangential springs are
  /// not incremented (a re-evaluation at the same state must not move them).
  void compute_forces() {
    sync_before_forces();
    evaluate_forces(0.0);
  }

 private:
  /// The mesh walls' positions and last loads from a checkpoint (load_state, load_state_union).
  void load_mesh_poses_and_loads(const StateArchive& a, const std::string& prefix);
  /// load_state_union's last phase: spreads the whole system over this run's ranks. With
  /// keep_schedule, at the positions of the saved run's last rebuild (x_build_of, by id), building
  /// the neighbour lists there and then putting the current positions back, so that later rebuilds
  /// fall on the saved run's steps; otherwise the first step rebuilds.
  void distribute_at_saved_rebuild(const std::unordered_map<GlobalId, Vec3>& x_build_of, bool keep_schedule);
  /// Forces at the current state; tangential springs advance by v_t * history_dt.
  /// finish = false: the caller reduces the loads itself (finish_forces) after the kick.
  void evaluate_forces(double history_dt, bool finish = true);
  /// Loads, broken-bond counts and the blow-up flag summed over ranks; returns "unstable anywhere".
  bool finish_forces(bool bad_here);
  bool unstable_here(double worst_v2) const;
  /// add_particle with a given id (the counter moves past it).
  std::size_t add_owned(const ParticleInit& p, GlobalId id);
  /// A particle of radius r joins the system somewhere (any rank): the skin and Eq. 2 follow it.
  void note_radius(double r);
  /// Contact-pair list, then the particles' water exposure (collective under MPI).
  void build_neighbors();
  void build_pair_list();
  /// build_pair_list's pieces: each particle's bond (and crushed-pair) partners as a CSR
  /// (partner_start_, partner_list_), and the contact history of the old list, by global ids.
  void build_partner_csr(std::size_t n);
  std::unordered_map<GidPair, Vec3, GidPairHash> take_contact_history();
  /// Every owned particle's ParticleExposure (water.h) from the bond list.
  void update_exposure();
  /// Under MPI: the ghost ends' exposure sums, reaches and counts added to their owners'.
  void exposure_ghosts_home();
  /// Neighbour rebuild; under MPI first migration, load balance and new ghost lists.
  void rebuild();
  /// Rebuild if anyone needs it, else refresh ghosts (collective under MPI).
  void sync_before_forces();
  // engine_parallel.cpp
  void exchange_full();  ///< drop_ghosts() then redistribute()
  /// Ghosts go: contact history to global-id keys, bond lengths measured (owned may be added now).
  void drop_ghosts();
  /// Load balance, migration to the owners, new ghost lists and bond bindings, bond counts.
  void redistribute();
  struct NewBond {
    GlobalId gi, gj;         ///< gi < gj
    std::uint32_t si, sj;    ///< their sites
  };
  /// The MPI half of insert_lattice (engine_insert.cpp).
  void insert_distributed(const LatticeInsert& lat, const std::vector<GlobalId>& gid, const std::vector<NewBond>& bonds,
                          const std::vector<LatticeInsert::Attach>& attach);
  void migrate(const std::vector<int>& dest, bool any_rank);
  /// One rank's migration message into this rank: particles, bonds and every per-pair record.
  void unpack_migration(const par::Bytes& in);
  void drop_owned(const std::vector<char>& keep);
  void make_ghosts();
  void forward_ghosts();
  void reverse_ghost_forces();
  double reduce_loads(double flag);
  void maybe_balance(bool force);
  std::vector<double> particle_work() const;
  void sort_spatially(const std::vector<std::uint32_t>& cell_of, std::uint32_t ncells);
  void field_forces();
  void wall_forces();
  /// Plane walls: the owned particles that can touch wall k before its list is refreshed
  /// (contact_kernel.cpp). Refreshed after every neighbour rebuild and whenever the wall moved
  /// more than half a skin along its normal (or turned) since; the others' springs are zero.
  void refresh_wall_candidates();
  /// Contact law against an immovable wall (plane or mesh) with the wall's friction.
  ContactResult wall_contact(double delta, double r, const Vec3& n, double vn, const Vec3& vt, double m,
                             double friction, Vec3& xi) const;
  void mesh_forces();
  void source_forces();
  template <class Law>
  void pair_forces(const Law& law);
  /// The particle-pair loop of the built-in laws, in blocks: gather, a branch-free vectorised
  /// law over the touching pairs, scatter in list order (contact_kernel.cpp). Same physics as
  /// pair_forces (round-off apart).
  void pair_kernel(const LinearLaw& law);
  void pair_kernel(const HertzLaw& law);
  template <class Law>
  void pair_kernel_impl(const Law& law);
  /// The plane walls' loop of the built-in laws, in blocks like the pair kernel (gather the
  /// touching candidates, the vectorised law, scatter in candidate order; contact_kernel.cpp).
  /// Same physics as the scalar loop of wall_forces (round-off apart). False: not a built-in law.
  bool wall_kernel();
  template <class Law>
  void wall_kernel_impl(const Law& law);
  const double* pair_smeff();
  void bond_forces();
  /// Bond::strength of the bond (gi, gj) of `kind`: its lattice_strength_spread factor for a
  /// lattice bond, 1 for any other.
  double bond_strength(GlobalId gi, GlobalId gj, BondKind kind) const {
    return kind == BondKind::Lattice ? bond_strength_factor(def_.lattice_strength_spread, gi, gj) : 1.0;
  }
  void kick_half();
  void check_blowup(std::uint32_t worst, double worst_v2, bool unstable_anywhere) const;
  double skin() const;
  double global_max(double v) const { return parallel() ? comm_->max(v) : v; }

  EngineDef def_;
  ParticleStore ps_;
  std::vector<Bond> bonds_;
  BondBatch bond_batch_;                 ///< SoA copy of bonds_ for the kernel (bond_kernel.h)
  std::vector<BrokenBond> broken_bonds_; ///< scratch of bond_forces
  /// Bonds broken in the last two steps while squeezed to an overlap beyond
  /// EngineDef::crushed_set_depth: the contact that replaces each starts that deep, so a blow-up
  /// report on its pair names the bond (check_blowup). Usually empty.
  struct SqueezedBreak {
    GlobalId gi, gj;
    double overlap_ratio;  ///< (r_i + r_j - |x_j - x_i|) / min(r_i, r_j) when it broke
    double strain;         ///< (r_i + r_j - |x_j - x_i|) / (r_i + r_j)
    std::uint64_t step;
    BondFailure mode;      ///< which strength it exceeded
  };
  std::vector<SqueezedBreak> squeezed_breaks_;
  const SqueezedBreak* squeezed_break(GlobalId a, GlobalId b) const;
  /// Pairs whose bond broke squeezed, with EngineDef::crushed_set: kept out of the contact list
  /// and computed by crushed_forces() on the overlap beyond `set` until they part (then they
  /// join the list). Keyed by global ids (a < b), on the rank that owns a (as bonds and contact
  /// history are), migrating and checkpointed with it (engine_crushed.cpp).
  struct CrushedContact {
    double set;  ///< m: the overlap the contact does not push back
    Vec3 xi;     ///< tangential spring, b's contact point relative to a's
  };
  struct GidPairLess {
    bool operator()(const GidPair& x, const GidPair& y) const { return x.a != y.a ? x.a < y.a : x.b < y.b; }
  };
  std::map<GidPair, CrushedContact, GidPairLess> crushed_;  ///< ordered: the same sums run to run
  void crushed_forces();
  double crushed_energy() const;
  /// The checkpoint's crushed pairs (none in one written before them); `clear` first.
  void load_crushed_pairs(const StateArchive& a, const std::string& p, bool clear);
  std::vector<ContactPair> pairs_;
  std::vector<double> pair_smeff_;  ///< per pair: sqrt(m_eff) (contact_kernel.cpp; cleared at rebuilds)
  std::vector<PlaneWall> walls_;
  std::vector<Vec3> wall_force_;
  std::vector<std::vector<Vec3>> wall_hist_;  ///< [wall][particle]
  std::vector<std::vector<std::uint32_t>> wall_cand_;  ///< [wall]: owned particles near it, ascending
  std::vector<PlaneWall> wall_at_cand_;                ///< [wall]: the wall when its list was made
  std::uint64_t wall_cand_rebuild_ = ~std::uint64_t{0};  ///< neighbor_rebuilds when the lists were made
  struct MeshWall {
    MeshWallDef def;
    std::unique_ptr<mesh::MeshGrid> grid;
    Vec3 position;
    MeshWallLoad load;
    struct Key {
      GlobalId gid;
      std::uint64_t feature;
      bool operator==(const Key& o) const { return gid == o.gid && feature == o.feature; }
    };
    struct KeyHash {
      std::size_t operator()(const Key& k) const { return std::hash<std::uint64_t>()(k.gid * 0x9E3779B97F4A7C15ull ^ k.feature); }
    };
    std::unordered_map<Key, Vec3, KeyHash> history, next_history;  ///< tangential springs
  };
  std::vector<MeshWall> meshes_;
  std::vector<ForceSource*> sources_;
  std::vector<ParticleExposure> exposure_;  ///< per owned particle, from the last rebuild
  /// In load_state_union: every particle's exposure by id (the whole system on every rank, so
  /// all ranks skip update_exposure alike), used by the restart's own rebuild.
  std::unordered_map<GlobalId, ParticleExposure> carried_exposure_;
  std::vector<Vec3> exposure_sum_, exposure_reach_pos_, exposure_reach_neg_;  ///< scratch of update_exposure (owned + ghosts)
  std::vector<std::uint32_t> exposure_count_;
  std::vector<mesh::MeshContact> mesh_contacts_;
  mesh::MeshQueryScratch mesh_scratch_;
  std::vector<Vec3> x_at_build_;
  /// step() set the owned particles' gravity and zero torque at this rebuild count, for this
  /// many owned particles (field_forces then skips that pass); ~0 = not set.
  std::uint64_t fields_preset_ = ~std::uint64_t{0};
  std::size_t fields_preset_n_ = 0;
  double max_disp2_ = INFINITY;
  bool forces_valid_ = false;
  bool need_rebuild_ = true;
  double dt_ = 0.0;
  bool dt_auto_ = true;            ///< dt follows Eq. 2 (def.dt == 0 and no set_dt)
  double min_radius_ = INFINITY;
  double history_dt_ = 0.0;        ///< spring-history increment of the current force evaluation
  double time_ = 0.0;
  std::uint64_t step_ = 0;
  StepStats stats_;
  bool walls_parked_ = false;      ///< set_walls_parked
  bool bonds_unbreakable_[2] = {false, false};  ///< set_bonds_unbreakable, by BondKind
  // overlap check of the last force pass
  double worst_overlap_ratio_ = 0.0;
  std::uint32_t worst_overlap_i_ = 0, worst_overlap_j_ = 0;
  int worst_overlap_source_ = -1;  ///< index into sources_ when a source holds the worst overlap
  // parallel state (engine_parallel.cpp)
  const par::Comm* comm_ = &par::serial();
  ParallelDef pdef_;
  par::Decomposition dom_;
  ParallelStats pstats_;
  std::vector<int> peers_;                             ///< ranks we exchange ghosts with (ascending)
  std::vector<std::vector<std::uint32_t>> ghost_send_; ///< per peer: our owned particles it holds as ghosts
  std::vector<std::uint32_t> ghost_start_, ghost_n_;   ///< per peer: its ghosts' range in our store
  double halo_ = 0.0;
  bool distributed_ = false;
  double max_bond_length_ = 0.0;
  std::uint64_t last_balance_step_ = 0;
  double force_seconds_since_balance_ = 0.0;
  std::unordered_map<GidPair, Vec3, GidPairHash> carried_history_;  ///< contact history between exchange and build
  /// The tangential springs of the listed pairs whose first particle's index is below `below`
  /// into carried_history_ (by global ids, oriented from the lower id), for the next build.
  void carry_pair_history(std::size_t below);
  std::vector<par::Bytes> fwd_send_, fwd_recv_, rev_send_, rev_recv_;  ///< ghost update buffers
  std::uint64_t broken_now_[3] = {0, 0, 0};            ///< tension, shear, compression breaks of this force evaluation
  // scratch for neighbour build
  std::vector<std::uint32_t> cell_start_, cell_items_, cell_of_;
  std::vector<std::uint32_t> partner_start_, partner_list_;
  BondSortScratch bond_sort_scratch_;
};

}  // namespace hs::bonded

#include "sim/report.h"

#include "bridge/conversion_criteria.h"
#include "common/error.h"
#include "common/ice_formulas.h"
#include "io/run_file_edit.h"
#include "parallel/comm.h"
#include "sim/build.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

namespace hs::sim {

namespace {

/// Gathers every rank's owned particles and intact bonds on rank 0 (collective) and finds
/// the pieces there; other ranks get an empty result.
analysis::Pieces gather_pieces(const bonded::Engine& e, const par::Comm& comm) {
  using analysis::PieceBond;
  using analysis::PieceParticle;
  const auto& p = e.particles();
  par::Bytes mine(p.owned() * sizeof(PieceParticle)), mine_b(e.bonds().size() * sizeof(PieceBond));
  for (std::size_t i = 0; i < p.owned(); ++i) {
    const PieceParticle r{p.gid[i], p.x[i].x(), p.x[i].y(), p.radius[i]};
    std::memcpy(mine.data() + i * sizeof(PieceParticle), &r, sizeof(PieceParticle));
  }
  for (std::size_t k = 0; k < e.bonds().size(); ++k) {
    const PieceBond r{e.bonds()[k].gi, e.bonds()[k].gj};
    std::memcpy(mine_b.data() + k * sizeof(PieceBond), &r, sizeof(PieceBond));
  }
  const par::Bytes all = comm.gather(mine), all_b = comm.gather(mine_b);
  if (comm.rank() != 0) return {};
  std::vector<PieceParticle> recs(all.size() / sizeof(PieceParticle));
  if (!recs.empty()) std::memcpy(static_cast<void*>(recs.data()), all.data(), all.size());
  std::vector<PieceBond> bonds(all_b.size() / sizeof(PieceBond));
  if (!bonds.empty()) std::memcpy(static_cast<void*>(bonds.data()), all_b.data(), all_b.size());
  return analysis::find_pieces(std::move(recs), bonds);
}

/// The ISO 19906 estimate beside the run (a parametric pier): inputs with their sources, the
/// ridge load, the keel frozen at the cone base, F_H with the highest particle as h_r.
void add_iso(RunReport& an, const Simulation& sim, const scene::Scene& s, const RunFigures& f) {
  if (!(s.gravity.norm() > 0)) {
    an.iso_note = "ISO 19906 estimate not computed: gravity is zero (the cone formulas need g > 0)";
  } else {
    try {
      IsoMeasured m;
      if (sim.built().lattice_thickness > 0) m.thickness = sim.built().lattice_thickness;
      if (f.has_pile_mean) m.rubble_height = f.max_pile_mean;
      m.at_peak = an.at_peak;
      m.ridge = sim.blocks().ridge;
      if (sim.built().calibrated.model == "calibrated") m.calibrated = sim.built().calibrated;
      const IsoAssembly as = assemble_iso_inputs(s, m);
      an.iso_in = as.in;
      an.iso_records = as.records;
      an.iso = analysis::compute_iso(an.iso_in);
      an.has_iso = true;
      // Any figure that is not finite (degenerate inputs) leaves the estimate out, with the reason.
      const nlohmann::json result = analysis::iso_to_json(an.iso);
      for (const auto& [k, v] : result.items())
        if (!std::isfinite(v.get<double>()) && an.has_iso) {
          an.has_iso = false;
          an.iso_note = "ISO 19906 estimate not computed: " + k + " is not finite for these inputs";
        }
      for (const auto& r : an.iso_records)
        if (!std::isfinite(r.value) && an.has_iso) {
          an.has_iso = false;
          an.iso_note = "ISO 19906 estimate not computed: input " + r.key + " is not finite";
        }
      if (an.has_iso && m.ridge && m.ridge->keel_depth > cone_base_depth(s)) {  // the keel frozen at the cone base
        m.keel_depth_limit = cone_base_depth(s);
        const analysis::IsoInputs fin = assemble_iso_inputs(s, m).in;
        const analysis::IsoResult fr = analysis::compute_iso(fin);
        if (std::isfinite(fr.F_total)) {
          an.has_iso_frozen = true;
          an.iso_frozen_in = fin;
          an.iso_frozen_depth = *m.keel_depth_limit;
          an.iso_frozen = fr;
        }
      }
      if (an.has_iso) {  // beside it: F_H with the old pile height, the highest particle
        analysis::IsoInputs top = an.iso_in;
        top.rubble_height = f.max_pile;
        try {
          const double fh = analysis::compute_iso(top).F_H;
          an.iso_F_H_top_particle = std::isfinite(fh) ? fh : 0.0;
        } catch (const InputError&) {
          an.iso_F_H_top_particle = 0.0;
        }
      }
    } catch (const InputError& err) {
      an.iso_note = std::string("ISO 19906 estimate not computed: ") + err.what();
    }
  }
}

}  // namespace

RunReport analyse_run(const Simulation& sim, const scene::Scene& s, const RunFigures& f, const par::Comm& comm,
                      const std::optional<PileAtLoadPeak>& at_peak) {
  RunReport an;
  an.pieces = gather_pieces(sim.engine(), comm);
  an.dem_peak = f.peak_h;
  an.max_pile = f.max_pile;
  const auto& hyb = sim.hybrid();
  an.has_hybrid = hyb.has_rigid();
  an.hybrid = hyb.report();
  an.block_bonds_broken = hyb.block_particle_bonds_broken();
  an.conversion = bridge::to_string(sim.blocks().def.mode);
  an.relax = hyb.relax_report();
  an.relax_origin = sim.relaxation_origin();
  an.rest_window = f.rest_window;
  an.final_mean_block_speed = f.final_mean_block_speed;
  an.final_mean_particle_speed = f.final_mean_particle_speed;
  if (const rigid::RigidWorld* w = hyb.world())
    for (const rigid::BlockId id : w->blocks())
      if (!w->fixed(id))
        an.final_max_block_speed = std::max(an.final_max_block_speed, w->velocity(id).norm() +
                                                                         w->angular_velocity(id).norm() *
                                                                             w->half_extents(id).norm());
  {
    const auto& ps = sim.engine().particles();
    double v2 = 0.0;
    for (std::size_t i = 0; i < ps.owned(); ++i) v2 = std::max(v2, ps.v[i].squaredNorm());
    if (comm.parallel()) comm.max(&v2, 1);
    an.final_max_particle_speed = std::sqrt(v2);
  }
  const double h_nominal = s.ice.has_consolidated_layer ? s.ice.consolidated_layer.thickness : s.ice.thickness;
  const double h_iso = sim.built().lattice_thickness > 0 ? sim.built().lattice_thickness : h_nominal;
  an.L_c = characteristic_length(s.material.youngs_modulus, h_iso, s.water.density, s.gravity.norm(),
                                 s.material.poisson_ratio);
  if (!std::isfinite(an.L_c)) {
    an.L_c_note = "L_c not defined: gravity is zero (L_c = (E h^3 / (12 (1 - nu^2) rho_w g))^(1/4) needs g > 0)";
    an.L_c = 0.0;
  }
  an.has_pile_mean = f.has_pile_mean;
  an.max_pile_mean = f.max_pile_mean;
  an.max_pile_mean_time = f.max_pile_mean_time;
  an.at_peak = at_peak;
  if (sim.has_structure() && s.structure.type == "pier") add_iso(an, sim, s, f);
  return an;
}

namespace {

void write_hybrid(io::RunFileEditor& f, const RunReport& a) {
  const std::string g = "/analysis/hybrid";
  f.add_group(g);
  const auto& r = a.hybrid;
  f.set_attribute(g, "conversion", a.conversion);
  const std::pair<const char*, double> figures[] = {
      {"conversions", static_cast<double>(r.conversions)},
      {"particles_created", static_cast<double>(r.particles_created)},
      {"bonds_created", static_cast<double>(r.bonds_created)},
      {"sites_dropped", static_cast<double>(r.sites_dropped)},
      {"conversions_freeze", static_cast<double>(r.conversions_freeze)},
      {"conversions_flexure", static_cast<double>(r.conversions_flexure)},
      {"conversions_crushing", static_cast<double>(r.conversions_by(bridge::kCrushingCriterion))},
      {"conversions_refused", static_cast<double>(r.conversions_refused)},
      {"max_utilisation", r.max_utilisation},
      {"blocks_moved_clear", static_cast<double>(r.blocks_moved_clear)},
      {"peak_particles", static_cast<double>(r.peak_particles)},
      {"blocks_initial", static_cast<double>(r.blocks_initial)},
      {"blocks_final", static_cast<double>(r.blocks_now)},
      {"rigid_steps", static_cast<double>(r.rigid_steps)},
      {"rigid_dt", r.rigid_dt},
      {"rigid_dt_limit", r.rigid_dt_limit},
      {"seconds_rigid", r.seconds_rigid},
      {"seconds_bonded", r.seconds_bonded},
      {"seconds_bridge", r.seconds_bridge},
      {"conversion_kinetic_energy_change", r.kinetic_energy_change},
      {"freeze_bonds_to_ice", static_cast<double>(r.ice_bonds_created)},
      {"freeze_bonds_from_joints", static_cast<double>(r.joints_to_bonds)},
      {"freeze_bonds_handed_over", static_cast<double>(r.block_bonds_handed_over)},
      {"freeze_bonds_unmatched", static_cast<double>(r.block_bonds_unmatched)},
      {"freeze_bonds_broken", static_cast<double>(a.block_bonds_broken)},
      {"final_max_block_speed", a.final_max_block_speed},
      {"final_max_particle_speed", a.final_max_particle_speed},
      {"final_mean_block_speed", a.final_mean_block_speed},
      {"final_mean_particle_speed", a.final_mean_particle_speed},
      {"rest_window", a.rest_window},
  };
  for (const auto& [name, value] : figures) f.set_attribute(g, name, value);
  f.set_attribute(g, "description", std::string("rigid/particle hybrid: conversions, particles created, peak particle "
                                                "count, wall time per part (s, rank 0), rigid step (s); at the end "
                                                "(the at-rest check): final_max_block_speed (centre speed + |omega| x "
                                                "half diagonal, m/s), final_mean_block_speed (the largest mean speed, "
                                                "path length over time, over the last rest_window s, m/s), final_max_particle_speed (m/s), "
                                                "final_mean_particle_speed (as the blocks', m/s)"));
}

/// /analysis/relaxation: what the relaxation before the freeze did (docs/bridge.md, "Relaxation").
void write_relaxation(io::RunFileEditor& f, const bridge::RelaxReport& r, const RelaxationOrigin& o) {
  const std::string g = "/analysis/relaxation";
  f.add_group(g);
  const std::pair<const char*, double> figures[] = {
      {"time", r.time},
      {"steps", static_cast<double>(r.steps)},
      {"rigid_steps", static_cast<double>(r.rigid_steps)},
      {"converged", static_cast<double>(r.converged)},
      {"at_rest", r.at_rest() ? 1.0 : 0.0},
      {"max_block_speed", r.max_block_speed},
      {"max_particle_speed", r.max_particle_speed},
      {"block_kinetic_energy", r.block_kinetic_energy},
      {"sheet_mean_dz", r.sheet_mean_dz},
      {"sheet_max_abs_dz", r.sheet_max_dz},
      {"sheet_peak_abs_mean_dz", r.sheet_peak_mean_dz},
      {"lattice_bonds_broken", static_cast<double>(r.lattice_bonds_broken)},
      {"max_time", r.def.max_time},
      {"speed", r.def.speed},
      {"hold", r.def.hold},
      {"damping", r.def.damping},
      {"lattice_damping", r.def.lattice_stage_damping()},
      {"hold_freeze_bonds", static_cast<double>(r.def.hold_freeze_bonds)},
      {"jointed_time", r.jointed_time},
      {"jointed_converged", static_cast<double>(r.jointed_converged)},
      {"jointed_joints", static_cast<double>(r.jointed_joints)},
      {"joints_overloaded", static_cast<double>(r.joints_overloaded)},
      {"freeze_bonds_held", static_cast<double>(r.freeze_bonds_held)},
      {"freeze_bonds_overloaded", static_cast<double>(r.freeze_bonds_overloaded)},
      {"unjointed_max_block_speed", r.unjointed_max_block_speed},
      {"lattice_time", r.lattice_time},
      {"lattice_converged", static_cast<double>(r.lattice_converged)},
      {"rigid_max_block_speed", r.rigid_max_block_speed},
  };
  for (const auto& [name, value] : figures) f.set_attribute(g, name, value);
  // Where it came from (docs/bridge.md, "The relaxation cache"): the figures above are the
  // relaxation's, steps_run what this process ran of it.
  f.set_attribute(g, "source", o.source);
  f.set_attribute(g, "relaxation_file", o.file);
  f.set_attribute(g, "key_hash", o.key_hash);
  f.set_attribute(g, "steps_run", static_cast<double>(o.steps_run));
  f.set_attribute(g, "description",
                  std::string("relaxation before the freeze joints and block-particle freeze bonds were made: "
                              "simulated time (s) and steps, converged (1: every block and particle slower than "
                              "speed for hold s in the first stage), at_rest (1: so at the freeze, after the "
                              "jointed stage when there was one), speeds at its end (m/s), block kinetic energy (J), the sheet's "
                              "vertical displacement at its end (m: mean, largest |dz|, largest |mean| during it), "
                              "lattice bonds broken in it; the jointed stage (blocks.relax.jointed_time): its time (s, "
                              "in time), converged (1: at rest), the joints it held unbreakable and those loaded "
                              "beyond their strength at its end, the fastest block when it began (m/s); the lattice stage "
                              "(blocks.relax.lattice_time, all_at_start after rigid stages): its time (s, in time), "
                              "converged (1: at rest), the fastest block when the rigid stages ended (m/s), its damping (1/s), "
                              "hold_freeze_bonds (1: the particle freeze bonds held in place, unbreakable, through it), "
                              "freeze_bonds_held and freeze_bonds_overloaded (those beyond their strength at its end); the run's "
                              "t = 0 is its end; source (computed: run by this process; loaded: from the relaxation "
                              "file relaxation_file, the cache entry of key key_hash or --relaxation; checkpoint: a "
                              "restart's), steps_run (DEM steps of relaxation this process ran: 0 unless computed)"));
}

/// /analysis/cost: one scalar dataset per phase (s; under MPI the mean over the ranks, the largest
/// as the attribute max_over_ranks), the wall time and the counts (docs/output.md).
void write_cost(io::RunFileEditor& f, const RunCost& c) {
  const std::string g = "/analysis/cost";
  f.add_group(g);
  const auto& info = phase_info();
  for (std::size_t k = 0; k < kPhaseCount; ++k) {
    const std::string d = g + "/" + info[k].name;
    f.add_scalar(d, c.seconds[k], "s", info[k].description);
    if (c.ranks > 1) f.set_attribute(d, "max_over_ranks", c.max[k]);
  }
  f.add_scalar(g + "/wall", c.wall, "s",
               "wall time of the run from the start of `hybridsim run` to the end of the analysis, every process "
               "of a restarted run together; the phases add up to it but for the gaps between them");
  if (c.ranks > 1) f.set_attribute(g + "/wall", "max_over_ranks", c.wall_max);
  f.add_scalar(g + "/steps", static_cast<double>(c.steps), "1", "DEM steps of the run (t = 0 to its end)");
  f.add_scalar(g + "/rigid_steps", static_cast<double>(c.rigid_steps), "1", "rigid steps of the run");
  f.add_scalar(g + "/particle_steps", c.particle_steps, "1", "particles summed over the run's steps (all ranks)");
  f.add_scalar(g + "/ranks", static_cast<double>(c.ranks), "1", "MPI ranks");
  f.add_scalar(g + "/processes", static_cast<double>(c.processes), "1",
               "processes that made the run: 1 + its restarts (each counted up to its last checkpoint)");
  f.set_attribute(g, "description",
                  std::string("wall time by phase (s, steady clock): set-up (read, calibration, build, relax_*, "
                              "freeze), step (particle_*, rigid_world, bridge_*), output, mpi_wait, analysis; "
                              "under MPI each dataset holds the mean over the ranks and max_over_ranks the "
                              "largest; a restarted run's figures cover every process (docs/output.md)"));
}

}  // namespace

std::string yardstick(const RunReport& a) {
  return a.iso.F_K > 0 ? "DEM/ISO (F_H + F_K)" : "DEM/ISO (F_H, no keel)";
}

std::string frozen_yardstick(const RunReport& a) {
  char b[64];
  std::snprintf(b, sizeof b, "%.3g", a.iso_frozen_depth);
  return std::string("DEM/ISO (keel frozen at ") + b + " m)";
}

namespace {

/// /analysis/iso: the results, every input (flat value attributes as before, and per input a
/// group /analysis/iso/inputs/<key> with value, unit, source and note), the DEM figures.
void write_iso(io::RunFileEditor& f, const RunReport& a) {
  const std::string g = "/analysis/iso";
  f.add_group(g);
  const nlohmann::json result = analysis::iso_to_json(a.iso);
  for (const auto& [k, v] : result.items()) f.set_attribute(g, k, v.get<double>());
  f.add_group(g + "/inputs");
  f.set_attribute(g + "/inputs", "description",
                  std::string("every input of the ISO 19906 estimate: value (SI), unit, source (scene, measured, "
                              "default, ridge_file or calibrated) and how it was obtained (docs/iso19906.md)"));
  for (const auto& r : a.iso_records) {
    f.set_attribute(g, r.key, r.value);
    const std::string gi = g + "/inputs/" + r.key;
    f.add_group(gi);
    f.set_attribute(gi, "value", r.value);
    f.set_attribute(gi, "unit", r.unit.empty() ? std::string("1") : r.unit);
    f.set_attribute(gi, "source", std::string(to_string(r.source)));
    f.set_attribute(gi, "origin", r.origin);
    if (!r.note.empty()) f.set_attribute(gi, "note", r.note);
  }
  f.set_attribute(g, "dem_peak_horizontal_force", a.dem_peak);
  f.set_attribute(g, "dem_max_pile_height", a.max_pile);
  if (a.has_pile_mean) f.set_attribute(g, "dem_max_pile_height_mean", a.max_pile_mean);
  if (a.has_pile_mean) f.set_attribute(g, "dem_max_pile_height_mean_time", a.max_pile_mean_time);
  if (a.at_peak) {
    f.set_attribute(g, "load_peak_window_start", a.at_peak->window.t0);
    f.set_attribute(g, "load_peak_window_end", a.at_peak->window.t1);
  }
  f.set_attribute(g, "dem_over_iso", analysis::dem_over_iso(a.dem_peak, a.iso));
  f.set_attribute(g, "dem_over_iso_yardstick", yardstick(a));
  f.set_attribute(g, "dem_over_iso_F_H", a.iso.F_H > 0 ? a.dem_peak / a.iso.F_H : 0.0);
  f.set_attribute(g, "dem_over_iso_F_H_yardstick", std::string("DEM/ISO (F_H only)"));
  if (a.has_iso_frozen) {
    f.set_attribute(g, "dem_over_iso_keel_frozen_yardstick", frozen_yardstick(a));
    f.set_attribute(g, "keel_frozen_depth", a.iso_frozen_depth);
    f.set_attribute(g, "keel_frozen_F_K", a.iso_frozen.F_K);
    f.set_attribute(g, "keel_frozen_F_total", a.iso_frozen.F_total);
    f.set_attribute(g, "dem_over_iso_keel_frozen", analysis::dem_over_iso(a.dem_peak, a.iso_frozen));
  }
  if (a.iso_F_H_top_particle > 0) {
    f.set_attribute(g, "F_H_top_particle_pile", a.iso_F_H_top_particle);
    f.set_attribute(g, "dem_over_iso_top_particle_pile", a.dem_peak / a.iso_F_H_top_particle);
  }
  f.set_attribute(g, "description",
                  std::string("ISO 19906 (Croasdale & Cammaert + Dolgopolov keel) load for the run's ice; inputs "
                              "and their sources in inputs/ (value, unit, source, origin, note); rubble_height = the "
                              "ISO-consistent pile height at the load peak (load_peak_window_start to _end) unless the "
                              "scene gives one, dem_max_pile_height_mean the run's maximum; dem_over_iso = dem_peak_horizontal_force / F_total (F_H + F_K, "
                              "the ridge load), dem_over_iso_F_H against the level-ice term alone; keel_frozen_* = the "
                              "estimate with the keel frozen at the cone base (keel_frozen_depth below the waterline); each "
                              "ratio's *_yardstick names what it is judged against; "
                              "F_H_top_particle_pile = F_H with the highest particle (dem_max_pile_height) as the pile "
                              "height instead; forces in N"));
}

}  // namespace

void write_analysis(const std::string& path, const RunReport& a) {
  io::RunFileEditor f(path);
  f.add_group("/analysis");
  f.add_group("/analysis/pieces");
  f.add_vector("/analysis/pieces/size", a.pieces.size, "1",
               "particles per piece (connected over intact bonds) at the end of the run, descending");
  f.add_vector("/analysis/pieces/extent", a.pieces.extent, "m",
               "max horizontal extent of each piece (larger side of its x-y bounding box, spheres included)");
  if (a.L_c_note.empty())
    f.set_attribute("/analysis/pieces", "characteristic_length", a.L_c);
  else
    f.set_attribute("/analysis/pieces", "characteristic_length_note", a.L_c_note);
  if (a.has_iso) write_iso(f, a);
  if (a.has_hybrid) write_hybrid(f, a);
  if (a.relax.ran) write_relaxation(f, a.relax, a.relax_origin);
  write_cost(f, a.cost);
  f.flush();
}

}  // namespace hs::sim

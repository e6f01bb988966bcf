#include "app/run_summary.h"

#include "app/text.h"
#include "parallel/comm.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace hs::app {

RunCounts print_setup(std::FILE* progress, const scene::Scene& s, const sim::Simulation& sim, double setup_s,
                      const par::Comm& comm) {
  const sim::RunStats st = sim.run_stats();
  const RunCounts n{st.particles, st.bonds};
  std::fprintf(progress,
               "hybridsim: %s: %lld particles, %lld bonds, %zu walls; dt = %.4g s, %llu steps to t = %g s "
               "(setup %.1f s)\n",
               s.name.c_str(), n.particles, n.bonds, s.walls.size(), st.dt,
               static_cast<unsigned long long>(sim.schedule().total_steps), s.time.duration, setup_s);
  if (st.has_blocks) {
    const sim::BlockReport& r = st.blocks;
    std::fprintf(progress,
                 "hybridsim: %zu rigid blocks (%zu freeze joints), conversion \"%s\"; rigid step %.4g s = %llu DEM "
                 "steps (stability limit %.4g s)\n",
                 r.blocks_initial, st.freeze_joints, st.conversion, r.rigid_dt,
                 static_cast<unsigned long long>(r.steps_per_rigid_step), r.rigid_dt_limit);
    if (r.blocks_moved_clear)
      std::fprintf(progress, "hybridsim: %zu blocks started overlapping the particles and were moved clear (at most %.3g m)\n",
                   r.blocks_moved_clear, r.max_clearing_shift);
    if (st.ice_joints)
      std::fprintf(progress, "hybridsim: %zu ridge joints to the ice sheet became %llu block-particle freeze bonds\n",
                   st.ice_joints, static_cast<unsigned long long>(r.ice_bonds_created));
    const sim::RelaxReport& x = st.relax;
    if (x.ran)
      std::fprintf(progress,
                   "hybridsim: relaxation before the freeze: %.4g s (%llu steps), %s; at its end fastest block %.3g "
                   "m/s, particle %.3g m/s, block KE %.3g J; sheet moved %.3g m on average (largest |dz| %.3g m), "
                   "%llu lattice bonds broken; t = 0 from here\n",
                   x.time, static_cast<unsigned long long>(x.steps), x.at_rest() ? "at rest" : "NOT at rest",
                   x.max_block_speed, x.max_particle_speed, x.block_kinetic_energy, x.sheet_mean_dz, x.sheet_max_dz,
                   static_cast<unsigned long long>(x.lattice_bonds_broken));
    const sim::RelaxationOrigin& o = sim.relaxation_origin();
    if (x.ran && o.source == "loaded")
      std::fprintf(progress, "hybridsim: relaxation loaded from %s (key %s): no step of it run here\n", o.file.c_str(),
                   o.key_hash.c_str());
    else if (x.ran && o.source == "computed" && !o.file.empty())
      std::fprintf(progress, "hybridsim: relaxation computed and cached in %s (key %s)\n", o.file.c_str(),
                   o.key_hash.c_str());
    if (x.ran && x.jointed_time > 0.0)
      std::fprintf(progress,
                   "hybridsim: of it, %.4g s with the %llu joints between blocks held (fastest block %.3g m/s when "
                   "it began), %s; %llu joints loaded beyond their strength at its end\n",
                   x.jointed_time, static_cast<unsigned long long>(x.jointed_joints), x.unjointed_max_block_speed,
                   x.jointed_converged ? "at rest" : "NOT at rest", static_cast<unsigned long long>(x.joints_overloaded));
    if (x.ran && x.lattice_time > 0.0)
      std::fprintf(progress,
                   "hybridsim: of it, %.4g s with every block converted at its relaxed pose (fastest block %.3g m/s "
                   "when the rigid stages ended), %s; %llu blocks made %llu particles, %llu sites dropped for "
                   "overlapping\n",
                   x.lattice_time, x.rigid_max_block_speed, x.lattice_converged ? "at rest" : "NOT at rest",
                   static_cast<unsigned long long>(r.conversions), static_cast<unsigned long long>(r.particles_created),
                   static_cast<unsigned long long>(r.sites_dropped));
    if (x.ran && x.lattice_time > 0.0 && x.def.hold_freeze_bonds)
      std::fprintf(progress,
                   "hybridsim: the lattice stage held %llu freeze bonds unbreakable; %llu loaded beyond their "
                   "strength at its end\n",
                   static_cast<unsigned long long>(x.freeze_bonds_held),
                   static_cast<unsigned long long>(x.freeze_bonds_overloaded));
  }
  if (comm.parallel()) {
    const auto& g = st.boxes;
    std::fprintf(progress, "hybridsim: %d MPI ranks, boxes %d x %d x %d, load balance every %llu steps by %s\n",
                 comm.size(), g[0], g[1], g[2], static_cast<unsigned long long>(s.parallel.balance_interval),
                 s.parallel.cost.c_str());
  }
  std::fflush(progress);
  return n;
}

namespace {

void print_blocks(std::ostream& out, const sim::RunStats& st, const sim::RunReport& an) {
  const sim::BlockReport& r = st.blocks;
  out << "  blocks (" << st.conversion << "): " << r.blocks_initial << " at the start, "
      << r.blocks_now << " rigid at the end; " << r.conversions << " conversions made " << r.particles_created
      << " particles (" << r.bonds_created << " bonds, " << r.sites_dropped << " overlapping sites dropped); peak "
      << r.peak_particles << " particles; " << r.rigid_steps << " rigid steps of " << sci(r.rigid_dt, 4)
      << " s; " << st.freeze_joints_broken << " freeze joints broken\n";
  if (st.solver_solves > 0)
    out << "  block solver: " << st.solver_solves << " solves, " << sci(double(st.solver_iterations) / st.solver_solves, 3)
        << " iterations per solve (most " << st.solver_max_iterations << " of " << st.solver_iteration_cap
        << "; blocks.solver_tolerance " << sci(st.solver_tolerance, 2) << " m/s; relaxation included)\n";
  if (st.far_sleep) {
    out << "  far sleep: " << st.awake_blocks << " blocks awake at the end; " << st.sleepers_woken_by_solve
        << " sleeping blocks woken by a change of their load (" << st.solves_repeated
        << " sub-step solves done again; counts since this process started)\n";
  }
  out << "  block-particle freeze bonds: " << r.ice_bonds_created << " at the start, " << r.joints_to_bonds
      << " made from joints of converted blocks, " << r.block_bonds_handed_over
      << " handed over to particle bonds at conversions (" << r.block_bonds_unmatched
      << " released with no new particle within 1.5 D), " << st.block_particle_bonds_broken << " broken\n";
  out << "  conversions governed by: freeze bonds " << r.conversions_freeze << ", flexure " << r.conversions_flexure
      << ", crushing " << st.conversions_crushing << "; " << r.conversions_refused << " refused by the converter (thinner than D or fully overlapped; left rigid); "
      << "largest utilisation seen " << sci(r.max_utilisation, 3) << "; conversion KE change "
      << sci(r.kinetic_energy_change, 3) << " J\n";
  const sim::RelaxReport& x = st.relax;
  if (x.ran)
    out << "  relaxation before the freeze: " << sci(x.time, 4) << " s, " << (x.at_rest() ? "at rest" : "NOT at rest")
        << " (fastest block " << sci(x.max_block_speed, 3) << " m/s, particle " << sci(x.max_particle_speed, 3)
        << " m/s at its end; sheet mean dz " << sci(x.sheet_mean_dz, 3) << " m)\n";
  if (an.rest_window > 0)
    out << "  at the end: fastest block " << sci(an.final_mean_block_speed, 3) << " m/s mean over the last "
        << sci(an.rest_window, 3) << " s (" << sci(an.final_max_block_speed, 3) << " m/s at the last step), particle "
        << sci(an.final_mean_particle_speed, 3) << " m/s (" << sci(an.final_max_particle_speed, 3)
        << " m/s at the last step)\n";
}

/// The ISO 19906 estimate: its inputs with their sources, the components, and each DEM/ISO
/// ratio named by its yardstick (sim::yardstick).
void print_iso(std::ostream& out, const sim::RunReport& an, const sim::RunFigures& f) {
  const auto& r = an.iso;
  const auto input = [&](const char* symbol, const char* key, double value, const char* unit, int prec) {
    std::string origin;
    for (const auto& rec : an.iso_records)
      if (rec.key == key) origin = rec.origin;
    return std::string(symbol) + " = " + sci(value, prec) + unit + " [" + origin + "]";
  };
  const auto& in = an.iso_in;
  out << "  ISO 19906 inputs: " << input("h", "thickness", in.thickness, " m", 4) << ", "
      << input("sigma_f", "flexural_strength", in.flexural_strength, " Pa", 4) << "\n    "
      << input("h_r", "rubble_height", in.rubble_height, " m", 4);
  if (an.has_pile_mean)
    out << ", the run's maximum " << sci(an.max_pile_mean, 4) << " m at t = " << sci(an.max_pile_mean_time, 4)
        << " s";
  out << "\n    " << input("theta", "rubble_slope_deg", in.rubble_slope_deg, " deg", 3) << ", "
      << input("e", "rubble_porosity", in.rubble_porosity, "", 3);
  if (in.keel_depth > 0)
    out << "\n    " << input("h_k", "keel_depth", in.keel_depth, " m", 4) << " below the consolidated layer, "
        << input("e_k", "keel_porosity", in.keel_porosity, "", 3) << ", "
        << input("w_k", "keel_width", in.keel_width, " m", 4);
  out << "\n  ISO 19906: H_B " << sci(r.H_B, 4) << ", H_P " << sci(r.H_P, 4) << ", H_R " << sci(r.H_R, 4) << ", H_L "
      << sci(r.H_L, 4) << ", H_T " << sci(r.H_T, 4) << ", F_H " << sci(r.F_H, 4) << ", F_K " << sci(r.F_K, 4)
      << " N\n";
  out << "  " << sim::yardstick(an) << " = " << sci(analysis::dem_over_iso(f.peak_h, r), 3) << ": DEM peak horizontal force "
      << sci(f.peak_h, 4) << " N vs ISO " << (r.F_K > 0 ? "F_H + F_K " : "F_H ") << sci(r.F_total, 4) << " N\n";
  if (r.F_K > 0) out << "  DEM/ISO (F_H only) = " << sci(r.F_H > 0 ? f.peak_h / r.F_H : 0.0, 3) << "\n";
  if (an.has_iso_frozen)
    out << "  " << sim::frozen_yardstick(an) << " = " << sci(analysis::dem_over_iso(f.peak_h, an.iso_frozen), 3)
        << ": the keel counted down to the cone base, " << sci(an.iso_frozen_depth, 3)
        << " m below the waterline (h_k = " << sci(an.iso_frozen_in.keel_depth, 3)
        << " m below the layer): F_H + F_K " << sci(an.iso_frozen.F_total, 4) << " N\n";
  if (an.iso_F_H_top_particle > 0)
    out << "  with the highest particle as h_r (" << sci(f.max_pile, 4) << " m): F_H " << sci(an.iso_F_H_top_particle, 4)
        << " N, DEM/ISO (F_H only) = " << sci(f.peak_h / an.iso_F_H_top_particle, 3) << "\n";
}

void print_pieces_and_iso(std::ostream& out, const sim::RunReport& an, const sim::RunFigures& f) {
  std::size_t multi = 0;
  for (auto n : an.pieces.size) multi += n >= 2;
  std::vector<double> ext;
  for (std::size_t k = 1; k < an.pieces.size.size(); ++k)
    if (an.pieces.size[k] >= 2) ext.push_back(an.pieces.extent[k]);
  std::sort(ext.begin(), ext.end());
  const double median = ext.empty() ? 0.0
                        : ext.size() % 2 ? ext[ext.size() / 2]
                                         : 0.5 * (ext[ext.size() / 2 - 1] + ext[ext.size() / 2]);
  out << "  pieces: " << multi << " with >= 2 particles (" << an.pieces.size.size() << " in all), largest "
      << (an.pieces.size.empty() ? 0 : an.pieces.size[0]) << " particles; median extent of broken-off pieces "
      << sci(median, 4) << " m (" << ext.size() << " pieces); "
      << (an.L_c_note.empty() ? "L_c = " + sci(an.L_c, 4) + " m" : an.L_c_note) << "\n";
  if (an.has_iso)
    print_iso(out, an, f);
  else if (!an.iso_note.empty())
    out << "  " << an.iso_note << "\n";
}

/// MPI figures (collective): the slowest rank sets the pace; comm time is exchanges + reductions.
void print_parallel(std::ostream& out, const sim::Simulation& sim, const sim::RunStats& st, double wall,
                    const par::Comm& comm) {
  double pf[3] = {st.force_seconds, st.comm_seconds, 0.0};
  const double force_time_sum = comm.sum(pf[0]);
  comm.max(pf, 2);
  const std::int64_t migrated = comm.sum(static_cast<std::int64_t>(st.migrated));
  comm.barrier();
  if (!comm.parallel()) return;
  out << "  MPI: " << comm.size() << " ranks; force time max/mean " << sci(pf[0] / std::max(force_time_sum / comm.size(), 1e-12), 3)
      << " (load imbalance), max comm time " << sci(pf[1], 3) << " s (" << sci(100.0 * pf[1] / std::max(wall, 1e-9), 3)
      << " % of wall), " << st.exchanges << " exchanges, " << migrated << " migrations, "
      << st.balances << " load balances\n";
  const char* axis = "xyz";  // where the load balance put the cuts (they follow the busy region)
  for (int a = 0; a < 3; ++a) {
    const auto& c = st.cuts[a];
    if (c.size() <= 2) continue;
    out << "  cuts across " << axis[a] << " at";
    for (std::size_t k = 1; k + 1 < c.size(); ++k) out << " " << sci(c[k], 4);
    out << " m (structure at " << axis[a] << " = " << (sim.has_structure() ? sci(sim.structure_position()[a], 4) : "-")
        << " m)\n";
  }
}

}  // namespace

void print_summary(std::ostream& out, const scene::Scene& s, const sim::Simulation& sim, const sim::RunFigures& f,
                   const sim::RunReport& an, const RunEnd& end, const par::Comm& comm) {
  const sim::RunStats st = sim.run_stats();  // collective (global counts)
  std::ostringstream mpi;  // collective: every rank reduces before rank 0 prints
  print_parallel(mpi, sim, st, end.wall_seconds, comm);
  const double wall = std::max(end.wall_seconds, 1e-9);
  // The rates are this process's: after a restart, the steps since its checkpoint.
  const std::uint64_t ran = st.step - std::min<std::uint64_t>(end.first_step, st.step);
  const double run = static_cast<double>(ran);
  out << "hybridsim: " << s.name << " finished: " << st.step << " steps to t = " << sci(st.time, 6) << " s";
  if (end.first_step > 0) out << "; restarted at step " << end.first_step << ", " << ran << " steps";
  out << " in " << sci(end.wall_seconds, 4) << " s wall (" << sci(run / wall, 4) << " steps/s, "
      << sci(static_cast<double>(end.start.particles) * run / wall, 3) << " particle-steps/s)\n";
  out << "  particles " << end.start.particles << " at the start, " << st.particles
      << " at the end; bonds " << end.start.bonds << ", broken " << st.bonds_broken << " ("
      << st.bonds_broken_tension << " tension, " << st.bonds_broken_shear << " shear"
      << (st.bonds_broken_compression || std::isfinite(s.bonds.compressive_strength_ratio)
              ? ", " + std::to_string(st.bonds_broken_compression) + " compression"
              : std::string())
      << ")\n";
  out << "  largest contact overlap " << sci(f.max_overlap, 3) << " of the particle radius at t = "
      << sci(f.max_overlap_time, 4) << " s (row maxima; limit stability.max_overlap_ratio = "
      << s.stability.max_overlap_ratio << ")\n";
  for (std::size_t w = 0; w < s.walls.size(); ++w)
    out << "  peak force on wall '" << s.walls[w].name << "': " << sci(f.wall_peak[w], 4) << " N at t = "
        << sci(f.wall_peak_time[w], 4) << " s\n";
  if (sim.has_structure()) {
    const Vec3& mean = f.mean_force;
    out << "  structure '" << s.structure.name << "': peak horizontal force " << sci(f.peak_h, 4)
        << " N at t = " << sci(f.peak_h_time, 4) << " s (output-interval means; single-step peak "
        << sci(f.peak_step, 4) << " N at t = " << sci(f.peak_step_time, 4) << " s); mean force ("
        << sci(mean.x(), 4) << ", " << sci(mean.y(), 4) << ", " << sci(mean.z(), 4) << ") N\n";
    out << "  max pile height " << sci(f.max_pile, 4) << " m at t = " << sci(f.max_pile_time, 4) << " s";
    if (f.has_pile_mean)
      out << "; ISO-consistent (mean over the waterline width) " << sci(f.max_pile_mean, 4) << " m at t = "
          << sci(f.max_pile_mean_time, 4) << " s";
    out << "\n";
  }
  if (st.has_blocks) print_blocks(out, st, an);
  print_pieces_and_iso(out, an, f);
  out << mpi.str();
  out << sim::cost_table(an.cost);
  out << "  output: " << end.output << " (" << f.rows << " series rows, " << f.snapshots << " snapshots)\n";
}

}  // namespace hs::app

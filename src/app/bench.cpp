// Built-in benchmarks, defined exactly as in the project's benchmark spec so that they
// can be compared side by side with other DEM codes on the same machine:
//   granular: 30,375 spheres (45 x 45 x 15), D = 0.5 m, rho = 920 kg/m^3, E = 1 GPa,
//             Kn = Kt = pi E D / 12, friction 0.3, restitution 0.3, gravity; a random
//             dense pack settled in a box with 5 walls (settling not timed); then 2000
//             steps at the Eq. 2 step are timed.
//   bonded:   an HCP plate of ~12,000 particles (same D, rho, E) with parallel bonds
//             between all lattice neighbours and the contact law between unbonded
//             pairs, on a floor, pushed at its edge by a 52-degree sloped indenter
//             moving at 0.4 m/s so that bonds bend and break; 4000 steps timed.
// Output: one JSON object on one line. Under mpirun the same system is spread over the ranks
// (strong scaling): particle_steps_per_s counts all particles; the figures of the parallel
// machinery (load imbalance, share of time in communication) come with it.
#include "app/bench.h"

#include "bonded/engine.h"
#include "bonded/hcp_lattice.h"
#include "common/ice_formulas.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <sys/resource.h>

namespace hs::app {

namespace {

using namespace hs::bonded;
using Clock = std::chrono::steady_clock;

constexpr double kD = 0.5, kRho = 920.0, kE = 1e9;

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // ru_maxrss is in KiB on Linux
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

EngineDef ice_def(double restitution, double friction) {
  EngineDef d;
  d.youngs_modulus = kE;
  d.density = kRho;
  d.contact.kn = d.contact.kt = eq1_contact_stiffness(kE, kD);  // paper Eq. 1
  d.contact.zeta_n = d.contact.zeta_t = damping_ratio_from_restitution(restitution);
  d.contact.mu = friction;
  return d;
}

ParticleInit sphere(const Vec3& x, bool lattice_cell) {
  ParticleInit p;
  p.x = x;
  p.radius = 0.5 * kD;
  p.mass = kRho * (lattice_cell ? hcp_cell_volume(kD) : kPi * kD * kD * kD / 6.0);
  p.buoyant_volume = 0.0;
  return p;
}

struct Timing {
  double wall_s;
  std::uint64_t steps;
};

Timing timed_run(Engine& e, std::uint64_t steps) {
  const auto t0 = Clock::now();
  e.run(steps);
  return {std::chrono::duration<double>(Clock::now() - t0).count(), steps};
}

Timing timed_run(Engine& e, std::uint64_t steps, ParallelStats& before) {
  e.comm().barrier();
  before = e.parallel_stats();
  return timed_run(e, steps);
}

nlohmann::json result(const std::string& name, const Engine& e, const Timing& t, double setup_s,
                      const ParallelStats& before) {
  const par::Comm& c = e.comm();
  const double n = static_cast<double>(e.global_particle_count());
  const double wall = c.max(t.wall_s);
  nlohmann::json j;
  j["name"] = name;
  j["particles"] = static_cast<std::int64_t>(n);
  j["steps"] = t.steps;
  j["wall_s"] = wall;
  j["particle_steps_per_s"] = n * t.steps / wall;
  j["peak_rss_mb"] = c.max(peak_rss_mb());  // per rank, the largest
  j["dt_s"] = e.dt();
  j["setup_s"] = setup_s;
  j["bonds"] = e.global_bond_count();
  j["contact_pairs"] = c.sum(static_cast<std::int64_t>(e.contact_pairs().size()));
  j["neighbor_rebuilds"] = e.stats().neighbor_rebuilds;
  j["threads"] = 1;
  j["ranks"] = c.size();
  if (c.parallel()) {
    const double force = e.parallel_stats().force_seconds - before.force_seconds;
    const double comm = e.parallel_stats().comm_seconds - before.comm_seconds;
    j["load_imbalance"] = c.max(force) / (c.sum(force) / c.size());  // max / mean force time
    j["comm_fraction"] = c.max(comm) / wall;
    j["ghosts"] = c.sum(static_cast<std::int64_t>(e.ghost_count()));
    const auto& g = e.decomposition().dims();
    j["grid"] = {g[0], g[1], g[2]};
  }
  j["cpu"] = cpu_model();
  j["version"] = HYBRIDSIM_VERSION;
  return j;
}

nlohmann::json granular(const par::Comm& comm) {
  const auto t0 = Clock::now();
  const int nx = 45, ny = 45, nz = 15;  // 30,375
  // Settling (not timed) uses frictionless, strongly damped contacts so that the
  // jittered grid collapses into a random dense pack quickly; the benchmark's own law
  // (friction 0.3, restitution 0.3) is then restored for the timed steps.
  EngineDef d = ice_def(0.1, 0.0);
  d.skin = 0.1 * kD;
  Engine e(d);
  e.particles().reserve(nx * ny * nz);
  const double a = 1.1 * kD;  // initial spacing: a loose jittered grid that collapses
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(-0.045 * kD, 0.045 * kD);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        e.add_particle(sphere(Vec3((i + 0.5) * a + u(rng), (j + 0.5) * a + u(rng), (k + 0.5) * a + u(rng)), false));
  const double L = nx * a;
  e.add_wall({"floor", Vec3(0, 0, 0), Vec3::UnitZ(), Vec3::Zero(), 0.3});
  e.add_wall({"x0", Vec3(0, 0, 0), Vec3::UnitX(), Vec3::Zero(), 0.3});
  e.add_wall({"x1", Vec3(L, 0, 0), -Vec3::UnitX(), Vec3::Zero(), 0.3});
  e.add_wall({"y0", Vec3(0, 0, 0), Vec3::UnitY(), Vec3::Zero(), 0.3});
  e.add_wall({"y1", Vec3(0, L, 0), -Vec3::UnitY(), Vec3::Zero(), 0.3});
  e.check_time_step();
  e.distribute(comm);
  // Settle until the mean speed is below 1 cm/s (or 20,000 steps).
  for (int block = 0; block < 100; ++block) {
    e.run(200);
    double v2 = 0;
    for (std::size_t i = 0; i < e.particles().owned(); ++i) v2 += e.particles().v[i].squaredNorm();
    if (std::sqrt(comm.sum(v2) / static_cast<double>(e.global_particle_count())) < 0.01) break;
  }
  e.mutable_def().contact.zeta_n = e.mutable_def().contact.zeta_t = damping_ratio_from_restitution(0.3);
  e.mutable_def().contact.mu = 0.3;
  e.run(1000);  // let friction take hold (not timed)
  e.check_time_step();
  const double setup = std::chrono::duration<double>(Clock::now() - t0).count();
  ParallelStats before;
  const Timing t = timed_run(e, 2000, before);
  auto j = result("granular", e, t, setup, before);
  double zmax = 0;
  for (std::size_t i = 0; i < e.particles().owned(); ++i) zmax = std::max(zmax, e.particles().x[i].z());
  zmax = comm.max(zmax);
  j["pack_height_m"] = zmax + 0.5 * kD;
  j["solid_fraction"] =
      static_cast<double>(e.global_particle_count()) * kPi * kD * kD * kD / 6.0 / (L * L * (zmax + 0.5 * kD));
  return j;
}

nlohmann::json bonded(const par::Comm& comm) {
  const auto t0 = Clock::now();
  EngineDef d = ice_def(0.3, 0.3);
  const double m = kRho * hcp_cell_volume(kD);
  const double I = 0.4 * m * 0.25 * kD * kD;
  // Parallel bonds with the paper's stiffness and a flexural-strength-like limit.
  d.bond[0] = ParallelBondParams::from_stiffness(d.contact.kn, d.contact.kt, 0.5 * kD, 0.6e6, 0.6e6, 0.1,
                                                 0.5 * m, 0.5 * I);
  Engine e(d);
  // 4 layers x ~3000 per layer: 32.5 m x 20 m plate, c-axis vertical.
  const Vec3 half(16.25, 10.0, 2.0 * hcp_layer_spacing(kD));
  // Bottom layer resting exactly on the floor (centre one radius above it).
  const auto centres =
      hcp_fill_box(half, Pose{Vec3(0, 0, half.z() - 0.5 * hcp_layer_spacing(kD) + 0.5 * kD), Quat::Identity()}, kD);
  e.particles().reserve(centres.size());
  for (const auto& c : centres) e.add_particle(sphere(c, true));
  e.bond_touching(0, e.particles().size(), BondKind::Lattice);
  e.add_wall({"floor", Vec3(0, 0, 0), Vec3::UnitZ(), Vec3::Zero(), 0.3});
  // Indenter: a plane sloped 52 deg from horizontal, like a cone face, touching the
  // plate's +x edge and moving into it at 0.4 m/s.
  double xmax = -INFINITY;
  for (const auto& c : centres) xmax = std::max(xmax, c.x());
  const double slope = 52.0 * kPi / 180.0;
  // Normal pointing into the ice and downwards: the slope rides over the edge and
  // pushes it down into the floor, bending the plate (a downward-breaking cone face).
  const Vec3 n(-std::sin(slope), 0.0, -std::cos(slope));
  e.add_wall({"indenter", Vec3(xmax + 0.5 * kD, 0, 2.0 * half.z()), n, Vec3(-0.4, 0, 0), 0.1});
  e.check_time_step();
  const std::size_t bonds0 = e.bonds().size();
  e.distribute(comm);
  const double setup = std::chrono::duration<double>(Clock::now() - t0).count();
  ParallelStats before;
  const Timing t = timed_run(e, 4000, before);
  auto j = result("bonded", e, t, setup, before);
  j["bonds_initial"] = bonds0;
  j["bonds_broken"] = e.stats().bonds_broken;
  j["indenter_force_N"] = {e.wall_force(1).x(), e.wall_force(1).y(), e.wall_force(1).z()};
  return j;
}

}  // namespace

std::vector<std::string> benchmark_names() { return {"granular", "bonded"}; }

int run_benchmark(const std::string& name, std::ostream& out, std::ostream& err, const par::Comm& comm) {
  nlohmann::json j;
  if (name == "granular") j = granular(comm);
  else if (name == "bonded") j = bonded(comm);
  else {
    err << "error: unknown benchmark '" << name << "'; available: granular, bonded\n";
    return 2;
  }
  out << j.dump() << std::endl;
  return 0;
}

}  // namespace hs::app

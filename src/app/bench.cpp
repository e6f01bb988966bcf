// Built-in benchmarks, defined exactly as in the project's benchmark spec so that they
// can be compared side by side with other DEM codes on the same machine:
//   granular: 30,375 spheres (45 x 45 x 15), D = 0.5 m, rho = 920 kg/m^3, E = 1 GPa,
//             Kn = Kt = pi E D / 12, friction 0.3, restitution 0.3, gravity; a random
//             dense pack settled in a box with 5 walls (settling not timed, and cached: see
//             granular_pack below); then 2000 steps at the Eq. 2 step are timed.
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
#include "common/error.h"
#include "common/ice_formulas.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <malloc.h>
#include <random>
#include <sstream>
#include <sys/resource.h>
#include <unistd.h>

namespace hs::app {

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

namespace {

using namespace hs::bonded;
using Clock = std::chrono::steady_clock;

constexpr double kD = 0.5, kRho = 920.0, kE = 1e9;

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // ru_maxrss is in KiB on Linux
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

// ---- the granular pack, cached ----
// Settling the pack takes ~45 s (up to 20,000 steps of 30,375 spheres), so the settled state (every
// particle's position, velocity, spin and wall springs, and the contact springs by pair) is kept
// in a file keyed by everything that shapes it; a later run loads it in well under a second. A
// run without the file settles on rank 0 (serially), writes the file and then, like a cached run,
// builds the benchmark engine from the same bytes: cached and uncached runs time identical work.
// Directory: $HYBRIDSIM_CACHE_DIR, else $XDG_CACHE_HOME/hybridsim, else ~/.cache/hybridsim;
// HYBRIDSIM_CACHE_DIR=off (or an unwritable directory) settles every time.

constexpr int kNx = 45, kNy = 45, kNz = 15;  // 30,375
constexpr double kSpacing = 1.1 * kD;        // initial spacing: a loose jittered grid that collapses
constexpr int kWalls = 5;

// Everything the settled pack depends on; a change here (or in the format) makes a new file.
std::string granular_pack_key() {
  std::ostringstream k;
  k.precision(17);
  k << "hybridsim-granular-pack v1 n=" << kNx << "x" << kNy << "x" << kNz << " D=" << kD << " rho=" << kRho
    << " E=" << kE << " spacing=" << kSpacing << " jitter=0.045D seed=2024 settle=(e0.1,mu0,<0.01m/s,200x100)"
    << " friction=(e0.3,mu0.3,wall0.3,1000) skin=0.1D";
  return k.str();
}

std::string cache_dir() {
  if (const char* d = std::getenv("HYBRIDSIM_CACHE_DIR")) return std::string(d) == "off" ? std::string() : d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d) return std::string(d) + "/hybridsim";
  if (const char* h = std::getenv("HOME"); h && *h) return std::string(h) + "/.cache/hybridsim";
  return {};
}

std::string pack_path() {
  const std::string dir = cache_dir();
  if (dir.empty()) return {};
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a of the key
  for (unsigned char c : granular_pack_key()) h = (h ^ c) * 1099511628211ull;
  char name[64];
  std::snprintf(name, sizeof name, "/granular-%016llx.pack", static_cast<unsigned long long>(h));
  return dir + name;
}

// Pack bytes: the key, then per particle in id order {x, v, omega, wall springs x5}, then the
// contact springs {a, b, xi}. Native byte order (a cache, not an exchange format).
struct PackParticle {
  Vec3 x, v, omega;
  Vec3 wall_xi[kWalls];
};

template <class T>
void put_pod(std::string& s, const T& v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}

template <class T>
bool get_pod(const std::string& s, std::size_t& at, T& v) {
  if (at + sizeof v > s.size()) return false;
  std::memcpy(&v, s.data() + at, sizeof v);
  at += sizeof v;
  return true;
}

void add_granular_walls(Engine& e) {
  const double L = kNx * kSpacing;
  e.add_wall({"floor", Vec3(0, 0, 0), Vec3::UnitZ(), Vec3::Zero(), 0.3});
  e.add_wall({"x0", Vec3(0, 0, 0), Vec3::UnitX(), Vec3::Zero(), 0.3});
  e.add_wall({"x1", Vec3(L, 0, 0), -Vec3::UnitX(), Vec3::Zero(), 0.3});
  e.add_wall({"y0", Vec3(0, 0, 0), Vec3::UnitY(), Vec3::Zero(), 0.3});
  e.add_wall({"y1", Vec3(0, L, 0), -Vec3::UnitY(), Vec3::Zero(), 0.3});
}

EngineDef granular_def() {
  EngineDef d = ice_def(0.3, 0.3);
  d.skin = 0.1 * kD;
  return d;
}

// Settles the pack serially and returns its bytes.
std::string settle_granular_pack() {
  // Settling uses frictionless, strongly damped contacts so that the jittered grid collapses into
  // a random dense pack quickly; the benchmark's own law (friction 0.3, restitution 0.3) is then
  // restored and run for 1000 steps so that friction takes hold.
  EngineDef d = ice_def(0.1, 0.0);
  d.skin = 0.1 * kD;
  Engine e(d);
  e.particles().reserve(kNx * kNy * kNz);
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(-0.045 * kD, 0.045 * kD);
  const double a = kSpacing;
  for (int k = 0; k < kNz; ++k)
    for (int j = 0; j < kNy; ++j)
      for (int i = 0; i < kNx; ++i)
        e.add_particle(sphere(Vec3((i + 0.5) * a + u(rng), (j + 0.5) * a + u(rng), (k + 0.5) * a + u(rng)), false));
  add_granular_walls(e);
  e.check_time_step();
  // Settle until the mean speed is below 1 cm/s (or 20,000 steps).
  for (int block = 0; block < 100; ++block) {
    e.run(200);
    double v2 = 0;
    for (std::size_t i = 0; i < e.particles().owned(); ++i) v2 += e.particles().v[i].squaredNorm();
    if (std::sqrt(v2 / static_cast<double>(e.particles().owned())) < 0.01) break;
  }
  e.mutable_def().contact.zeta_n = e.mutable_def().contact.zeta_t = damping_ratio_from_restitution(0.3);
  e.mutable_def().contact.mu = 0.3;
  e.run(1000);
  const ParticleStore& p = e.particles();
  std::vector<PackParticle> out(p.owned());
  for (std::size_t i = 0; i < p.owned(); ++i) {
    PackParticle& q = out[p.gid[i]];
    q.x = p.x[i];
    q.v = p.v[i];
    q.omega = p.omega[i];
    for (int k = 0; k < kWalls; ++k) q.wall_xi[k] = e.wall_history(k, i);
  }
  std::string s;
  const std::string key = granular_pack_key();
  put_pod(s, static_cast<std::uint64_t>(key.size()));
  s += key;
  put_pod(s, static_cast<std::uint64_t>(out.size()));
  s.append(reinterpret_cast<const char*>(out.data()), out.size() * sizeof(PackParticle));
  const std::vector<PairHistory> h = e.contact_history();
  put_pod(s, static_cast<std::uint64_t>(h.size()));
  s.append(reinterpret_cast<const char*>(h.data()), h.size() * sizeof(PairHistory));
  return s;
}

// Where a pack's particles and springs lie in its bytes (checked against the key and sizes).
struct PackView {
  const char* parts = nullptr;
  std::size_t n_parts = 0;
  const char* hist = nullptr;
  std::size_t n_hist = 0;
  PackParticle particle(std::size_t k) const {
    PackParticle p;
    std::memcpy(static_cast<void*>(&p), parts + k * sizeof(PackParticle), sizeof p);
    return p;
  }
  std::vector<PairHistory> history() const {
    std::vector<PairHistory> h(n_hist);
    std::memcpy(static_cast<void*>(h.data()), hist, n_hist * sizeof(PairHistory));
    return h;
  }
};

// The view of a pack, or false if the bytes are not a pack of this key.
bool read_pack(const std::string& s, PackView& view) {
  std::size_t at = 0;
  std::uint64_t n = 0;
  if (!get_pod(s, at, n) || at + n > s.size() || s.compare(at, n, granular_pack_key()) != 0) return false;
  at += n;
  if (!get_pod(s, at, n) || n != static_cast<std::uint64_t>(kNx * kNy * kNz) || at + n * sizeof(PackParticle) > s.size())
    return false;
  view.parts = s.data() + at;
  view.n_parts = n;
  at += n * sizeof(PackParticle);
  if (!get_pod(s, at, n) || at + n * sizeof(PairHistory) != s.size()) return false;
  view.hist = s.data() + at;
  view.n_hist = n;
  return true;
}

// The settled pack's bytes, from the cache or settled now (on rank 0, then broadcast).
std::string granular_pack(const par::Comm& comm, bool& cached) {
  const std::string path = pack_path();
  std::string s;
  if (comm.rank() == 0 && !path.empty()) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (in) {
      s.resize(static_cast<std::size_t>(in.tellg()));
      in.seekg(0);
      in.read(s.data(), static_cast<std::streamsize>(s.size()));
      if (!in) s.clear();
    }
    PackView view;
    if (!read_pack(s, view)) s.clear();
  }
  cached = !s.empty();
  if (comm.rank() == 0 && s.empty()) {
    s = settle_granular_pack();
    if (!path.empty()) {
      std::error_code ec;
      std::filesystem::create_directories(cache_dir(), ec);
      const std::string tmp = path + ".tmp" + std::to_string(::getpid());
      std::ofstream out(tmp, std::ios::binary);
      out.write(s.data(), static_cast<std::streamsize>(s.size()));
      out.close();
      if (out) std::filesystem::rename(tmp, path, ec);
      else std::filesystem::remove(tmp, ec);
    }
  }
  if (comm.parallel()) {
    s = comm.broadcast(s);
    cached = comm.max(cached ? 1.0 : 0.0) > 0.0;
  }
  return s;
}

// The pack as a LAMMPS data file (atom_style sphere: id type diameter density x y z; velocities
// with spins), for tools/bench/granular.lmp.
void write_lammps_data(const std::string& file, const PackView& pack) {
  std::vector<PackParticle> parts(pack.n_parts);
  for (std::size_t k = 0; k < parts.size(); ++k) parts[k] = pack.particle(k);
  std::ofstream o(file);
  if (!o) throw InputError("/bench/lammps-data", "cannot write '" + file + "'; give a writable path");
  o.precision(17);
  const double L = kNx * kSpacing;
  double zmax = 0;
  for (const auto& p : parts) zmax = std::max(zmax, p.x.z());
  o << "hybridsim bench granular pack: " << granular_pack_key() << "\n\n"
    << parts.size() << " atoms\n1 atom types\n\n"
    << "0 " << L << " xlo xhi\n0 " << L << " ylo yhi\n0 " << std::ceil(zmax + 2.0 * kD) << " zlo zhi\n\nAtoms # sphere\n\n";
  for (std::size_t k = 0; k < parts.size(); ++k)
    o << k + 1 << " 1 " << kD << " " << kRho << " " << parts[k].x.x() << " " << parts[k].x.y() << " " << parts[k].x.z()
      << "\n";
  o << "\nVelocities\n\n";
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const auto& p = parts[k];
    o << k + 1 << " " << p.v.x() << " " << p.v.y() << " " << p.v.z() << " " << p.omega.x() << " " << p.omega.y() << " "
      << p.omega.z() << "\n";
  }
}

nlohmann::json granular(const par::Comm& comm, const BenchOptions& opt) {
  const auto t0 = Clock::now();
  bool cached = false;
  Engine e(granular_def());
  {  // (the pack's bytes are freed before the timed steps)
    std::string bytes = granular_pack(comm, cached);
    PackView pack;
    if (!read_pack(bytes, pack)) throw std::runtime_error("bench granular: the settled pack is malformed");
    if (!opt.lammps_data.empty() && comm.rank() == 0) write_lammps_data(opt.lammps_data, pack);
    add_granular_walls(e);
    e.particles().reserve(pack.n_parts);
    for (std::size_t i = 0; i < pack.n_parts; ++i) {
      const PackParticle q = pack.particle(i);
      ParticleInit p = sphere(q.x, false);
      p.v = q.v;
      p.omega = q.omega;
      e.add_particle(p);
      for (int k = 0; k < kWalls; ++k) e.set_wall_history(k, i, q.wall_xi[k]);
    }
    std::vector<PairHistory> hist = pack.history();
    bytes = {};
    e.set_contact_history(hist);
  }
  e.check_time_step();
  e.distribute(comm);
  const double setup = std::chrono::duration<double>(Clock::now() - t0).count();
  ParallelStats before;
  const Timing t = timed_run(e, 2000, before);
  auto j = result("granular", e, t, setup, before);
  j["pack_cached"] = cached;
  double zmax = 0;
  for (std::size_t i = 0; i < e.particles().owned(); ++i) zmax = std::max(zmax, e.particles().x[i].z());
  zmax = comm.max(zmax);
  const double L = kNx * kSpacing;
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

std::vector<std::string> benchmark_names() { return {"granular", "bonded", "hybrid"}; }

int run_benchmark(const std::string& name, std::ostream& out, std::ostream& err, const par::Comm& comm,
                  const BenchOptions& opt) {
  // Large blocks (> 256 KiB: the pack, particle arrays, pair lists) are mapped and unmapped on
  // their own, so that memory freed after set-up (the pack's copies) leaves the process instead
  // of raising glibc's adaptive threshold and staying in the heap: peak_rss_mb then measures the
  // engine, not the allocator's history.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
  nlohmann::json j;
  if (name == "granular") j = granular(comm, opt);
  else if (name == "bonded") j = bonded(comm);
  else if (name == "hybrid") j = hybrid_benchmark(comm, opt);
  else {
    err << "error: unknown benchmark '" << name << "'; available: granular, bonded, hybrid\n";
    return 2;
  }
  out << j.dump() << std::endl;
  return 0;
}

}  // namespace hs::app

#include "app/run.h"

#include "analysis/iso19906.h"
#include "app/hybrid_setup.h"
#include "analysis/pile_height.h"
#include "bonded/engine.h"
#include "common/error.h"
#include "common/ice_formulas.h"
#include "io/run_file.h"
#include "parallel/comm.h"
#include "scene/scene.h"

#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace hs::app {

namespace {

using Clock = std::chrono::steady_clock;

std::string duration_text(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const long t = std::lround(s);
  char buf[64];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

std::string sci(double x, int prec = 3) {
  std::ostringstream s;
  s << std::setprecision(prec) << x;
  return s.str();
}

struct Schedule {
  double dt = 0;
  std::uint64_t total_steps = 0;
  std::uint64_t output_every = 1;    ///< steps between series rows
  std::uint64_t snapshot_every = 0;  ///< 0 = no snapshots
};

Schedule schedule(const scene::Scene& s, double dt) {
  Schedule sc;
  sc.dt = dt;
  sc.total_steps = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(s.time.duration / dt - 1e-9)));
  sc.output_every = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(s.time.output_interval / dt)));
  if (s.time.snapshot_interval > 0)
    sc.snapshot_every =
        std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(s.time.snapshot_interval / dt)));
  return sc;
}

/// Rough resident memory of the engine for n particles and b bonds.
double memory_estimate_bytes(std::size_t n, std::size_t bonds, std::size_t walls) {
  const double per_particle = 5 * sizeof(Vec3) + sizeof(Quat) + 5 * sizeof(double) + sizeof(GlobalId) +
                              sizeof(bonded::MaterialIndex) + 2 + sizeof(Vec3) /*x at build*/ +
                              3 * sizeof(std::uint32_t) /*cells*/ + walls * sizeof(Vec3) /*wall history*/ +
                              32 /*gid index*/ + 4 * sizeof(bonded::ContactPair) /*contacts, assumed*/;
  return n * per_particle + bonds * (sizeof(bonded::Bond) + 8 /*partner lists*/);
}

/// Pieces of ice: connected components of the particles over intact bonds.
struct Pieces {
  std::vector<std::int64_t> size;  ///< particles per piece, descending
  std::vector<double> extent;      ///< m, max horizontal extent of each piece (same order)
};

/// Gathers every rank's owned particles and bonds on rank 0 (collective) and finds the pieces
/// there; other ranks get an empty result. Particles are taken in global-id order, so the result
/// does not depend on the rank count.
Pieces find_pieces(const bonded::Engine& e, const par::Comm& comm) {
  struct Rec {
    GlobalId gid;
    double x, y, r;
  };
  struct BondRec {
    GlobalId a, b;
  };
  const auto& p = e.particles();
  par::Bytes mine(p.owned() * sizeof(Rec)), mine_b(e.bonds().size() * sizeof(BondRec));
  for (std::size_t i = 0; i < p.owned(); ++i) {
    const Rec r{p.gid[i], p.x[i].x(), p.x[i].y(), p.radius[i]};
    std::memcpy(mine.data() + i * sizeof(Rec), &r, sizeof(Rec));
  }
  for (std::size_t k = 0; k < e.bonds().size(); ++k) {
    const BondRec r{e.bonds()[k].gi, e.bonds()[k].gj};
    std::memcpy(mine_b.data() + k * sizeof(BondRec), &r, sizeof(BondRec));
  }
  const par::Bytes all = comm.gather(mine), all_b = comm.gather(mine_b);
  if (comm.rank() != 0) return {};
  std::vector<Rec> recs(all.size() / sizeof(Rec));
  if (!recs.empty()) std::memcpy(static_cast<void*>(recs.data()), all.data(), all.size());
  std::vector<BondRec> bonds(all_b.size() / sizeof(BondRec));
  if (!bonds.empty()) std::memcpy(static_cast<void*>(bonds.data()), all_b.data(), all_b.size());
  std::sort(recs.begin(), recs.end(), [](const Rec& a, const Rec& b) { return a.gid < b.gid; });
  std::unordered_map<GlobalId, std::uint32_t> index;
  index.reserve(recs.size() * 2);
  for (std::size_t i = 0; i < recs.size(); ++i) index.emplace(recs[i].gid, static_cast<std::uint32_t>(i));
  const std::size_t n = recs.size();
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t a) {
    while (parent[a] != a) {
      parent[a] = parent[parent[a]];
      a = parent[a];
    }
    return a;
  };
  for (const auto& b : bonds) {
    const auto ia = index.find(b.a), ib = index.find(b.b);
    if (ia == index.end() || ib == index.end()) continue;
    const std::uint32_t a = find(ia->second), c = find(ib->second);
    if (a != c) parent[std::max(a, c)] = std::min(a, c);
  }
  struct Acc {
    std::int64_t count = 0;
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  };
  std::vector<std::int64_t> slot(n, -1);
  std::vector<Acc> acc;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t r = find(static_cast<std::uint32_t>(i));
    if (slot[r] < 0) {
      slot[r] = static_cast<std::int64_t>(acc.size());
      acc.emplace_back();
    }
    Acc& a = acc[slot[r]];
    const Rec& q = recs[i];
    ++a.count;
    a.x0 = std::min(a.x0, q.x - q.r);
    a.x1 = std::max(a.x1, q.x + q.r);
    a.y0 = std::min(a.y0, q.y - q.r);
    a.y1 = std::max(a.y1, q.y + q.r);
  }
  std::stable_sort(acc.begin(), acc.end(), [](const Acc& a, const Acc& b) { return a.count > b.count; });
  Pieces out;
  for (const auto& a : acc) {
    out.size.push_back(a.count);
    out.extent.push_back(std::max(a.x1 - a.x0, a.y1 - a.y0));
  }
  return out;
}

/// Appends the /analysis groups to a closed run file (HDF5 C API; RunFile has no attributes).
struct H5 {
  hid_t id = -1;
  explicit H5(hid_t h, const std::string& what) : id(h) {
    if (h < 0) throw std::runtime_error("HDF5: cannot " + what);
  }
  ~H5() {
    if (id < 0) return;
    switch (H5Iget_type(id)) {
      case H5I_FILE: H5Fclose(id); break;
      case H5I_GROUP: H5Gclose(id); break;
      case H5I_DATASET: H5Dclose(id); break;
      case H5I_DATASPACE: H5Sclose(id); break;
      case H5I_ATTR: H5Aclose(id); break;
      case H5I_DATATYPE: H5Tclose(id); break;
      case H5I_GENPROP_LST: H5Pclose(id); break;
      default: break;
    }
  }
  H5(const H5&) = delete;
  H5& operator=(const H5&) = delete;
};

void h5check(herr_t rc, const std::string& what) {
  if (rc < 0) throw std::runtime_error("HDF5: cannot " + what);
}

void h5_attr(hid_t obj, const std::string& name, double v) {
  H5 sp(H5Screate(H5S_SCALAR), "create a dataspace");
  H5 a(H5Acreate2(obj, name.c_str(), H5T_NATIVE_DOUBLE, sp.id, H5P_DEFAULT, H5P_DEFAULT), "create attribute " + name);
  h5check(H5Awrite(a.id, H5T_NATIVE_DOUBLE, &v), "write attribute " + name);
}

void h5_attr(hid_t obj, const std::string& name, const std::string& v) {
  H5 t(H5Tcopy(H5T_C_S1), "copy a string type");
  H5Tset_size(t.id, std::max<std::size_t>(1, v.size()));
  H5 sp(H5Screate(H5S_SCALAR), "create a dataspace");
  H5 a(H5Acreate2(obj, name.c_str(), t.id, sp.id, H5P_DEFAULT, H5P_DEFAULT), "create attribute " + name);
  h5check(H5Awrite(a.id, t.id, v.c_str()), "write attribute " + name);
}

void h5_vector(hid_t group, const std::string& name, hid_t mem_type, const void* data, std::size_t n,
               const std::string& units, const std::string& description) {
  const hsize_t dims[1] = {static_cast<hsize_t>(n)};
  H5 sp(H5Screate_simple(1, dims, nullptr), "create a dataspace");
  const hid_t file_type = mem_type == H5T_NATIVE_DOUBLE ? H5T_IEEE_F64LE : H5T_STD_I64LE;
  H5 d(H5Dcreate2(group, name.c_str(), file_type, sp.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
       "create dataset " + name);
  if (n) h5check(H5Dwrite(d.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "write dataset " + name);
  h5_attr(d.id, "units", units);
  h5_attr(d.id, "description", description);
}

struct AnalysisOut {
  Pieces pieces;
  double L_c = 0.0;
  bool has_iso = false;
  analysis::IsoInputs iso_in;
  analysis::IsoResult iso;
  double dem_peak = 0.0;      ///< N, peak horizontal force on the structure (output-row means)
  double max_pile = 0.0;      ///< m
  bool has_hybrid = false;
  bridge::HybridReport hybrid;
  std::uint64_t block_bonds_broken = 0;  ///< block-particle freeze bonds broken
  std::string conversion;
};

void write_analysis(const std::string& path, const AnalysisOut& a) {
  H5 fapl(H5Pcreate(H5P_FILE_ACCESS), "create file access properties");
  h5check(H5Pset_file_locking(fapl.id, 1, 1), "set file locking");  // as the run file was created
  H5 f(H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl.id), "reopen " + path + " to add /analysis");
  H5 g(H5Gcreate2(f.id, "/analysis", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /analysis");
  {
    H5 p(H5Gcreate2(g.id, "pieces", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /analysis/pieces");
    h5_vector(p.id, "size", H5T_NATIVE_INT64, a.pieces.size.data(), a.pieces.size.size(), "1",
              "particles per piece (connected over intact bonds) at the end of the run, descending");
    h5_vector(p.id, "extent", H5T_NATIVE_DOUBLE, a.pieces.extent.data(), a.pieces.extent.size(), "m",
              "max horizontal extent of each piece (larger side of its x-y bounding box, spheres included)");
    h5_attr(p.id, "characteristic_length", a.L_c);
  }
  if (a.has_iso) {
    H5 i(H5Gcreate2(g.id, "iso", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /analysis/iso");
    const auto r = analysis::iso_to_json(a.iso);
    for (const auto& [k, v] : r.items()) h5_attr(i.id, k, v.get<double>());
    const auto in = analysis::iso_inputs_to_json(a.iso_in);
    for (const auto& [k, v] : in.items()) h5_attr(i.id, k, v.get<double>());
    h5_attr(i.id, "dem_peak_horizontal_force", a.dem_peak);
    h5_attr(i.id, "dem_max_pile_height", a.max_pile);
    h5_attr(i.id, "dem_over_iso", a.iso.F_H > 0 ? a.dem_peak / a.iso.F_H : 0.0);
    h5_attr(i.id, "description", std::string("ISO 19906 (Croasdale & Cammaert) cone load for the scene's ice, "
                                             "rubble_height = max simulated pile height; forces in N"));
  }
  if (a.has_hybrid) {
    H5 h(H5Gcreate2(g.id, "hybrid", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /analysis/hybrid");
    const auto& r = a.hybrid;
    h5_attr(h.id, "conversion", a.conversion);
    const std::pair<const char*, double> figures[] = {
        {"conversions", static_cast<double>(r.conversions)},
        {"particles_created", static_cast<double>(r.particles_created)},
        {"bonds_created", static_cast<double>(r.bonds_created)},
        {"sites_dropped", static_cast<double>(r.sites_dropped)},
        {"conversions_freeze", static_cast<double>(r.conversions_freeze)},
        {"conversions_flexure", static_cast<double>(r.conversions_flexure)},
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
    };
    for (const auto& [name, value] : figures) h5_attr(h.id, name, value);
    h5_attr(h.id, "description", std::string("rigid/particle hybrid: conversions, particles created, peak particle "
                                             "count, wall time per part (s, rank 0), rigid step (s)"));
  }
  h5check(H5Fflush(f.id, H5F_SCOPE_GLOBAL), "flush " + path);
}

void print_warnings(const scene::Scene& s, std::FILE* err) {
  for (const auto& w : s.warnings) std::fprintf(err, "warning: %s\n", w.c_str());
}

}  // namespace

int check_scene(const RunOptions& opt, std::ostream& out, std::ostream& err) {
  const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
  for (const auto& w : s.warnings) err << "warning: " << w << "\n";
  scene::Built b = scene::build_engine(s, false);
  const bonded::Engine& e = *b.engine;
  const double dt = e.dt(), crit = e.critical_time_step();
  const Schedule sc = schedule(s, dt);
  const double psteps = static_cast<double>(b.particles) * sc.total_steps;
  const std::uint64_t rows = sc.total_steps / sc.output_every + 1;
  const std::uint64_t snaps = sc.snapshot_every ? sc.total_steps / sc.snapshot_every + 1 : 0;
  const double file_bytes = snaps * b.particles * (7 * 8 + 4 + 8) + rows * (8 * 16 + 6 * s.walls.size() * 8);
  out << "scene:            " << s.name << (s.description.empty() ? "" : " - " + s.description) << "\n";
  out << "particles:        " << b.particles << " (D = " << s.material.particle_diameter << " m, "
      << b.layout.layers << " layers";
  if (b.layout.consolidated_layers) out << ", " << b.layout.consolidated_layers << " in the consolidated layer";
  out << "; ice top z = " << sci(b.layout.top_z, 4) << " m, bottom z = " << sci(b.layout.bottom_z, 4) << " m)\n";
  out << "bonds:            " << b.bonds << " (" << sci(b.particles ? 2.0 * b.bonds / b.particles : 0.0, 3)
      << " per particle)\n";
  out << "walls:            " << s.walls.size() << "\n";
  if (b.structure >= 0) {
    const auto& st = s.structure;
    std::string parts;
    for (const auto& p : b.structure_parts) parts += (parts.empty() ? "" : ", ") + p;
    out << "structure:        '" << st.name << "' (" << st.type << "; parts " << parts << "), widest radius "
        << sci(b.structure_radius, 4) << " m, at (" << st.position.transpose() << ") m, velocity ("
        << st.velocity.transpose() << ") m/s\n";
  }
  if (s.has_blocks) {
    HybridSetup hsu = hybrid_setup(s);
    for (const auto& w : hsu.warnings) err << "warning: " << w << "\n";
    const bridge::ConversionMode mode = hsu.def.mode;
    hsu.def.mode = bridge::ConversionMode::Never;  // count and check only; convert nothing here
    double vol = 0.0;
    for (const auto& bi : hsu.blocks) vol += 8.0 * bi.def.half_extents.prod();
    const double D = s.material.particle_diameter;
    const double est = vol / (D * D * D / std::sqrt(2.0));  // particles if all were converted
    bridge::HybridSystem hs(*b.engine, hsu.def, hsu.blocks, hsu.joints);  // InputError at /blocks/rigid_dt
    const auto& r = hs.report();
    out << "blocks:           " << hsu.blocks.size() << " rigid (" << hsu.ridge_blocks_in_file << " in the ridge file), "
        << hsu.joints.size() << " freeze joints, " << sci(vol, 4) << " m^3 of ice (~" << sci(est, 3)
        << " particles if all converted); conversion \"" << bridge::to_string(mode) << "\"\n";
    out << "rigid step:       " << sci(r.rigid_dt, 4) << " s = " << r.steps_per_rigid_step
        << " DEM steps (stability limit " << sci(r.rigid_dt_limit, 4) << " s)\n";
  }
  out << "time step:        dt = " << sci(dt, 4) << " s" << (s.time.dt == 0 ? " (paper Eq. 2)" : "")
      << ", critical dt = " << sci(crit, 4) << " s (margin x" << sci(crit / dt, 3) << ")\n";
  out << "steps:            " << sc.total_steps << " for " << s.time.duration << " s; " << rows
      << " series rows, " << snaps << " snapshots\n";
  out << "estimated memory: " << sci(memory_estimate_bytes(b.particles, b.bonds, s.walls.size()) / 1048576.0, 3)
      << " MiB; output file ~" << sci(file_bytes / 1048576.0, 3) << " MiB\n";
  out << "estimated time:   " << duration_text(psteps / kParticleStepsPerSecond) << " (" << sci(psteps, 3)
      << " particle-steps at ~" << sci(kParticleStepsPerSecond, 2) << "/s, one core)\n";
  out << "output:           " << (opt.output.empty() ? s.output : opt.output) << "\n";
  e.check_time_step();  // InputError at /time/dt, after the figures that explain it
  out << "ok\n";
  return 0;
}

int run_scene(const RunOptions& opt, std::ostream& out, std::FILE* progress) {
  const par::Comm& comm = opt.comm ? *opt.comm : par::serial();
  const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
  print_warnings(s, progress);
  const auto t_setup = Clock::now();
  scene::Built b = scene::build_engine(s, true);
  bonded::Engine& e = *b.engine;
  const HybridSetup hsetup = hybrid_setup(s);
  for (const auto& w : hsetup.warnings) std::fprintf(progress, "warning: %s\n", w.c_str());
  bridge::HybridSystem hyb(e, hsetup.def, hsetup.blocks, hsetup.joints, hsetup.ice_joints);
  if (comm.parallel()) {  // every rank built the whole scene; each keeps its share
    bonded::ParallelDef pd;
    pd.grid = s.parallel.grid;
    pd.balance_interval = s.parallel.balance_interval;
    pd.cost = s.parallel.cost == "time" ? bonded::ParallelDef::Cost::Time : bonded::ParallelDef::Cost::Work;
    e.distribute(comm, pd);
  }
  const Schedule sc = schedule(s, e.dt());
  const std::size_t nwalls = s.walls.size();

  io::RunFileMeta meta;
  meta.scene_text = s.json.dump(2);
  meta.program_version = HYBRIDSIM_VERSION;
  meta.comm = &comm;
  const std::string out_path = opt.output.empty() ? s.output : opt.output;
  io::RunFile file(out_path, meta);

  const int id_time = file.add_series("/series/time", 1, "s", "simulated time");
  const int id_step = file.add_int_series("/series/step", 1, "1", "step number");
  const bool has_st = b.structure >= 0;
  const std::size_t nparts = b.structure_parts.size();
  const int id_force = file.add_series(
      "/series/force", 3, "N",
      has_st ? "force exerted by the ice on the structure, mean over the output interval ending at time"
             : "total force exerted by the ice on all walls, mean over the output interval ending at time");
  std::vector<int> id_wall(nwalls);
  for (std::size_t k = 0; k < nwalls; ++k)
    id_wall[k] = file.add_series("/series/walls/" + s.walls[k].name + "/force", 3, "N",
                                 "force on wall '" + s.walls[k].name + "', mean over the output interval");
  int id_moment = -1, id_pile = -1, id_pos = -1;
  std::vector<int> id_pf(nparts), id_pm(nparts);
  if (has_st) {
    id_moment = file.add_series("/series/moment", 3, "N m",
                                "moment of the ice loads on the structure about its mesh origin (moving with it), "
                                "mean over the output interval");
    for (std::size_t k = 0; k < nparts; ++k) {
      const std::string& pn = b.structure_parts[k];
      id_pf[k] = file.add_series("/series/parts/" + pn + "/force", 3, "N",
                                 "force on structure part '" + pn + "', mean over the output interval");
      id_pm[k] = file.add_series("/series/parts/" + pn + "/moment", 3, "N m",
                                 "moment on structure part '" + pn + "' about the mesh origin, mean over the interval");
    }
    id_pile = file.add_series("/series/pile_height", 1, "m",
                              "highest ice above the waterline over the upstream half of the structure, within "
                              "its widest radius + one particle diameter of the axis");
    id_pos = file.add_series("/series/structure_position", 3, "m", "position of the structure's mesh origin");
  }
  struct EnergySeries {
    const char* name;
    const char* description;
    int id;
  };
  EnergySeries en[] = {
      {"kinetic", "kinetic energy, translational + rotational", 0},
      {"kinetic_translational", "translational kinetic energy", 0},
      {"kinetic_rotational", "rotational kinetic energy", 0},
      {"gravity_potential", "gravitational potential energy (reference z = 0)", 0},
      {"buoyancy_potential", "buoyancy potential energy", 0},
      {"bond_elastic", "elastic energy in intact bonds", 0},
      {"contact_elastic", "elastic energy in contacts", 0},
      {"total", "sum of the above", 0},
  };
  for (auto& x : en) x.id = file.add_series(std::string("/series/energy/") + x.name, 1, "J", x.description);
  const int id_broken = file.add_int_series("/series/bonds_broken", 1, "1", "bonds broken since the start");
  const int id_bonds = file.add_int_series("/series/bonds", 1, "1", "intact bonds");
  const int id_particles = file.add_int_series("/series/particles", 1, "1", "particles");
  int id_blk_force = -1, id_blk_ke = -1, id_blk_count = -1, id_blk_conv = -1, id_blk_joints = -1;
  if (hyb.has_rigid()) {
    if (has_st)
      id_blk_force = file.add_series("/series/blocks/structure_force", 3, "N",
                                     "the rigid blocks' share of /series/force (contact impulses on the structure "
                                     "per rigid step), mean over the output interval");
    id_blk_ke = file.add_series("/series/blocks/kinetic_energy", 1, "J", "kinetic energy of the rigid blocks");
    id_blk_count = file.add_int_series("/series/blocks/count", 1, "1", "rigid blocks (not yet converted)");
    id_blk_conv = file.add_int_series("/series/blocks/conversions", 1, "1", "blocks converted into particles so far");
    id_blk_joints = file.add_int_series("/series/blocks/joints_broken", 1, "1", "freeze joints between blocks broken");
  }

  std::vector<Vec3> force_sum(nwalls, Vec3::Zero());
  Vec3 st_force_sum = Vec3::Zero(), st_moment_sum = Vec3::Zero(), blk_force_sum = Vec3::Zero();
  std::vector<Vec3> pf_sum(nparts, Vec3::Zero()), pm_sum(nparts, Vec3::Zero());
  std::uint64_t force_count = 0;
  std::vector<double> peak(nwalls, 0.0), peak_time(nwalls, 0.0);
  double st_peak_h = 0.0, st_peak_h_time = 0.0;    // horizontal |F| of the row means
  double st_peak_step = 0.0, st_peak_step_time = 0.0;  // horizontal |F| of single steps
  double max_pile = 0.0, max_pile_time = 0.0;
  Vec3 st_force_total = Vec3::Zero();              // for the mean over the run
  std::uint64_t st_force_n = 0;

  analysis::PileProbe probe;
  if (has_st) {
    const Vec3& v = s.structure.velocity;
    probe.upstream = Vec3(v.x(), v.y(), 0.0).norm() > 0 ? Vec3(v.x(), v.y(), 0.0).normalized() : Vec3::UnitX();
    probe.reach = b.structure_radius + s.material.particle_diameter;
    probe.water_level = s.water.enabled ? s.water.level : 0.0;
  }

  auto write_row = [&]() {
    const double t = e.time();
    const std::int64_t st = static_cast<std::int64_t>(e.step_count());
    file.append(id_time, &t);
    file.append(id_step, &st);
    const double inv = force_count ? 1.0 / static_cast<double>(force_count) : 0.0;
    Vec3 total = Vec3::Zero();
    for (std::size_t k = 0; k < nwalls; ++k) {
      const Vec3 f = force_count ? Vec3(force_sum[k] * inv) : e.wall_force(static_cast<int>(k));
      total += f;
      file.append(id_wall[k], f.data());
      force_sum[k].setZero();
    }
    if (has_st) {
      const auto& L = e.mesh_wall_load(b.structure);
      const Vec3 f = force_count ? Vec3(st_force_sum * inv) : L.force;
      const Vec3 m = force_count ? Vec3(st_moment_sum * inv) : L.moment;
      file.append(id_force, f.data());
      file.append(id_moment, m.data());
      for (std::size_t k = 0; k < nparts; ++k) {
        const Vec3 pf = force_count ? Vec3(pf_sum[k] * inv) : L.part_force[k];
        const Vec3 pm = force_count ? Vec3(pm_sum[k] * inv) : L.part_moment[k];
        file.append(id_pf[k], pf.data());
        file.append(id_pm[k], pm.data());
        pf_sum[k].setZero();
        pm_sum[k].setZero();
      }
      st_force_sum.setZero();
      st_moment_sum.setZero();
      const double fh = std::hypot(f.x(), f.y());
      if (fh > st_peak_h) {
        st_peak_h = fh;
        st_peak_h_time = t;
      }
      probe.axis_point = e.mesh_wall_position(b.structure);
      const auto& ps = e.particles();
      const double ph = comm.max(analysis::pile_height(probe, ps.x.data(), ps.radius.data(), ps.owned()));
      file.append(id_pile, &ph);
      file.append(id_pos, probe.axis_point.data());
      if (ph > max_pile) {
        max_pile = ph;
        max_pile_time = t;
      }
    } else {
      file.append(id_force, total.data());
    }
    if (hyb.has_rigid()) {
      if (id_blk_force >= 0) {
        const Vec3 bf = force_count ? Vec3(blk_force_sum * inv) : hyb.structure_force();
        file.append(id_blk_force, bf.data());
        blk_force_sum.setZero();
      }
      const double ke = hyb.rigid_kinetic_energy();
      const std::int64_t nblk = static_cast<std::int64_t>(hyb.world()->block_count());
      const std::int64_t nconv = static_cast<std::int64_t>(hyb.report().conversions);
      const std::int64_t nj = static_cast<std::int64_t>(hyb.world()->broken_joint_count());
      file.append(id_blk_ke, &ke);
      file.append(id_blk_count, &nblk);
      file.append(id_blk_conv, &nconv);
      file.append(id_blk_joints, &nj);
    }
    force_count = 0;
    const auto E = e.energy();
    const double v[] = {E.kinetic_translational + E.kinetic_rotational,
                        E.kinetic_translational,
                        E.kinetic_rotational,
                        E.gravity_potential,
                        E.buoyancy_potential,
                        E.bond_elastic,
                        E.contact_elastic,
                        E.total()};
    for (std::size_t k = 0; k < std::size(en); ++k) file.append(en[k].id, &v[k]);
    const std::int64_t broken = static_cast<std::int64_t>(e.stats().bonds_broken);
    const std::int64_t nb = e.global_bond_count();
    const std::int64_t np = e.global_particle_count();
    file.append(id_broken, &broken);
    file.append(id_bonds, &nb);
    file.append(id_particles, &np);
  };

  std::vector<std::int32_t> ibuf;
  std::vector<std::int64_t> lbuf;
  auto write_snapshot = [&]() {
    e.refresh_bond_counts();  // bonds may have broken on the neighbouring rank
    const auto& p = e.particles();
    const std::size_t n = p.owned();
    // This rank's rows: after the lower ranks' particles.
    const io::FieldSlice sl{comm.exscan(n), static_cast<std::uint64_t>(e.global_particle_count())};
    file.begin_snapshot(e.time(), e.step_count());
    file.write_field("position", p.x.data()->data(), n, 3, "m", sl);
    file.write_field("velocity", p.v.data()->data(), n, 3, "m/s", sl);
    file.write_field("radius", p.radius.data(), n, 1, "m", sl);
    ibuf.assign(p.bond_count.begin(), p.bond_count.begin() + n);
    file.write_field("bond_count", ibuf.data(), n, 1, "1", sl);
    lbuf.assign(p.gid.begin(), p.gid.begin() + n);
    file.write_field("global_id", lbuf.data(), n, 1, "1", sl);
    file.end_snapshot();
  };

  const bool tty = isatty(fileno(progress)) != 0;
  const double setup_s = std::chrono::duration<double>(Clock::now() - t_setup).count();
  // Counted now: all_at_start conversion has added the blocks' particles and bonds.
  const auto n_particles = static_cast<long long>(e.global_particle_count());
  const auto n_bonds = static_cast<long long>(e.global_bond_count());
  std::fprintf(progress,
               "hybridsim: %s: %lld particles, %lld bonds, %zu walls; dt = %.4g s, %llu steps to t = %g s "
               "(setup %.1f s)\n",
               s.name.c_str(), n_particles, n_bonds, nwalls, e.dt(), static_cast<unsigned long long>(sc.total_steps),
               s.time.duration, setup_s);
  if (hyb.has_rigid()) {
    const auto& r = hyb.report();
    std::fprintf(progress,
                 "hybridsim: %zu rigid blocks (%zu freeze joints), conversion \"%s\"; rigid step %.4g s = %llu DEM "
                 "steps (stability limit %.4g s)\n",
                 r.blocks_initial, hsetup.joints.size(), bridge::to_string(hsetup.def.mode), r.rigid_dt,
                 static_cast<unsigned long long>(r.steps_per_rigid_step), r.rigid_dt_limit);
    if (r.blocks_moved_clear)
      std::fprintf(progress, "hybridsim: %zu blocks started overlapping the particles and were moved clear (at most %.3g m)\n",
                   r.blocks_moved_clear, r.max_clearing_shift);
    if (!hsetup.ice_joints.empty())
      std::fprintf(progress, "hybridsim: %zu ridge joints to the ice sheet became %llu block-particle freeze bonds\n",
                   hsetup.ice_joints.size(), static_cast<unsigned long long>(r.ice_bonds_created));
  }
  if (comm.parallel()) {
    const auto& g = e.decomposition().dims();
    std::fprintf(progress, "hybridsim: %d MPI ranks, boxes %d x %d x %d, load balance every %llu steps by %s\n",
                 comm.size(), g[0], g[1], g[2], static_cast<unsigned long long>(s.parallel.balance_interval),
                 s.parallel.cost.c_str());
  }
  std::fflush(progress);

  const auto t0 = Clock::now();
  auto last_report = t0;
  std::uint64_t last_report_step = 0;
  double rate = 0.0;  // steps/s, smoothed
  bool progress_line_open = false;

  try {
    // Row 0 is the initial state (forces are zero until the first step; Engine::compute_forces
    // cannot be called before the first neighbour build).
    write_row();
    if (sc.snapshot_every) write_snapshot();
    file.flush();
    for (std::uint64_t k = 1; k <= sc.total_steps; ++k) {
      hyb.step();
      for (std::size_t w = 0; w < nwalls; ++w) {
        const Vec3& f = e.wall_force(static_cast<int>(w));
        force_sum[w] += f;
        const double m = f.norm();
        if (m > peak[w]) {
          peak[w] = m;
          peak_time[w] = e.time();
        }
      }
      if (has_st) {
        const auto& L = e.mesh_wall_load(b.structure);
        // Particles' load (this DEM step) + blocks' load (the current rigid step's mean).
        const Vec3 f = L.force + hyb.structure_force();
        st_force_sum += f;
        st_moment_sum += L.moment + hyb.structure_moment();
        blk_force_sum += hyb.structure_force();
        const auto& bpf = hyb.structure_part_force();
        const auto& bpm = hyb.structure_part_moment();
        for (std::size_t q = 0; q < nparts; ++q) {
          pf_sum[q] += L.part_force[q] + (q < bpf.size() ? bpf[q] : Vec3::Zero());
          pm_sum[q] += L.part_moment[q] + (q < bpm.size() ? bpm[q] : Vec3::Zero());
        }
        st_force_total += f;
        ++st_force_n;
        const double fh = std::hypot(f.x(), f.y());
        if (fh > st_peak_step) {
          st_peak_step = fh;
          st_peak_step_time = e.time();
        }
      }
      ++force_count;
      if (k % sc.output_every == 0 || k == sc.total_steps) write_row();
      if (sc.snapshot_every && (k % sc.snapshot_every == 0 || k == sc.total_steps)) write_snapshot();
      if ((k & 63) == 0 || k == sc.total_steps) {
        const auto now = Clock::now();
        const double since = std::chrono::duration<double>(now - last_report).count();
        const double interval = tty ? 0.5 : 10.0;
        if (since >= interval || (k == sc.total_steps && tty)) {
          const double inst = (k - last_report_step) / std::max(since, 1e-9);
          rate = rate == 0.0 ? inst : 0.5 * rate + 0.5 * inst;
          const double left = (sc.total_steps - k) / std::max(rate, 1e-9);
          const double elapsed = std::chrono::duration<double>(now - t0).count();
          if (tty) {
            std::fprintf(progress, "\r  t = %.4g / %g s  step %llu/%llu  %.0f steps/s  %s left  bonds broken %llu   ",
                         e.time(), s.time.duration, static_cast<unsigned long long>(k),
                         static_cast<unsigned long long>(sc.total_steps), rate, duration_text(left).c_str(),
                         static_cast<unsigned long long>(e.stats().bonds_broken));
            progress_line_open = true;
          } else {
            std::fprintf(progress,
                         "[%s] t = %.4g / %g s, step %llu/%llu, %.0f steps/s, %s left, bonds broken %llu\n",
                         duration_text(elapsed).c_str(), e.time(), s.time.duration,
                         static_cast<unsigned long long>(k), static_cast<unsigned long long>(sc.total_steps), rate,
                         duration_text(left).c_str(), static_cast<unsigned long long>(e.stats().bonds_broken));
          }
          std::fflush(progress);
          last_report = now;
          last_report_step = k;
        }
      }
    }
  } catch (const SimulationError&) {
    if (progress_line_open) std::fprintf(progress, "\n");
    file.close();  // keep what was written so far (collective: every rank saw the same error)
    std::fprintf(progress, "hybridsim: output up to t = %g s kept in %s\n", e.time(), out_path.c_str());
    throw;
  } catch (const std::exception& ex) {
    if (!comm.parallel()) throw;
    // Under MPI an error may have struck this rank alone; closing the file (collective) would
    // wait for the others forever. Report and end all ranks; the file holds the last flush.
    std::fprintf(stderr, "error (rank %d): %s; aborting all ranks, %s holds the output up to the last flush\n",
                 comm.rank(), ex.what(), out_path.c_str());
    comm.abort(1);
  }
  if (progress_line_open) std::fprintf(progress, "\n");
  const std::size_t rows = file.series_rows(id_time), snaps = file.snapshot_count();
  file.close();
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();

  // ---- end-of-run analysis: broken pieces, ISO 19906 next to the DEM ----
  AnalysisOut an;
  an.pieces = find_pieces(e, comm);
  an.dem_peak = st_peak_h;
  an.max_pile = max_pile;
  an.has_hybrid = hyb.has_rigid();
  an.hybrid = hyb.report();
  an.block_bonds_broken = hyb.block_particle_bonds_broken();
  an.conversion = bridge::to_string(hsetup.def.mode);
  const double h_iso = s.ice.has_consolidated_layer ? s.ice.consolidated_layer.thickness : s.ice.thickness;
  an.L_c = characteristic_length(s.material.youngs_modulus, h_iso, s.water.density, s.gravity.norm(),
                                 s.material.poisson_ratio);
  std::string iso_note;
  if (has_st && s.structure.type == "pier") {
    try {
      an.iso_in = scene::iso_inputs(s, max_pile);
      an.iso = analysis::compute_iso(an.iso_in);
      an.has_iso = true;
    } catch (const InputError& err) {
      iso_note = std::string("ISO 19906 estimate not computed: ") + err.what();
    }
  }
  comm.barrier();  // every rank's close has completed before rank 0 reopens the file
  if (comm.rank() == 0) write_analysis(out_path, an);  // rank 0 adds /analysis
  // Parallel figures: the slowest rank sets the pace; comm time is exchanges + reductions.
  double pf[3] = {e.parallel_stats().force_seconds, e.parallel_stats().comm_seconds, 0.0};
  const double force_time_sum = comm.sum(pf[0]);
  comm.max(pf, 2);
  const std::int64_t migrated = comm.sum(static_cast<std::int64_t>(e.parallel_stats().migrated));
  comm.barrier();

  const auto& st = e.stats();
  out << "hybridsim: " << s.name << " finished: " << e.step_count() << " steps to t = " << sci(e.time(), 6)
      << " s in " << sci(wall, 4) << " s wall (" << sci(e.step_count() / std::max(wall, 1e-9), 4) << " steps/s, "
      << sci(static_cast<double>(n_particles) * e.step_count() / std::max(wall, 1e-9), 3)
      << " particle-steps/s)\n";
  out << "  particles " << n_particles << " at the start, " << e.global_particle_count() << " at the end; bonds "
      << n_bonds << ", broken " << st.bonds_broken << " ("
      << st.bonds_broken_tension << " tension, " << st.bonds_broken_shear << " shear)\n";
  for (std::size_t w = 0; w < nwalls; ++w)
    out << "  peak force on wall '" << s.walls[w].name << "': " << sci(peak[w], 4) << " N at t = "
        << sci(peak_time[w], 4) << " s\n";
  if (has_st) {
    const Vec3 mean = st_force_n ? Vec3(st_force_total / static_cast<double>(st_force_n)) : Vec3::Zero();
    out << "  structure '" << s.structure.name << "': peak horizontal force " << sci(st_peak_h, 4)
        << " N at t = " << sci(st_peak_h_time, 4) << " s (output-interval means; single-step peak "
        << sci(st_peak_step, 4) << " N at t = " << sci(st_peak_step_time, 4) << " s); mean force ("
        << sci(mean.x(), 4) << ", " << sci(mean.y(), 4) << ", " << sci(mean.z(), 4) << ") N\n";
    out << "  max pile height " << sci(max_pile, 4) << " m at t = " << sci(max_pile_time, 4) << " s\n";
  }
  if (hyb.has_rigid()) {
    const auto& r = hyb.report();
    out << "  blocks (" << bridge::to_string(hsetup.def.mode) << "): " << r.blocks_initial << " at the start, "
        << r.blocks_now << " rigid at the end; " << r.conversions << " conversions made " << r.particles_created
        << " particles (" << r.bonds_created << " bonds, " << r.sites_dropped << " overlapping sites dropped); peak "
        << r.peak_particles << " particles; " << r.rigid_steps << " rigid steps of " << sci(r.rigid_dt, 4)
        << " s; " << hyb.world()->broken_joint_count() << " freeze joints broken\n";
    out << "  block-particle freeze bonds: " << r.ice_bonds_created << " at the start, " << r.joints_to_bonds
        << " made from joints of converted blocks, " << r.block_bonds_handed_over
        << " handed over to particle bonds at conversions (" << r.block_bonds_unmatched
        << " released with no new particle within 1.5 D), " << hyb.block_particle_bonds_broken() << " broken\n";
    out << "  conversions governed by: freeze bonds " << r.conversions_freeze << ", flexure " << r.conversions_flexure
        << "; " << r.conversions_refused << " refused by the converter (thinner than D or fully overlapped; left rigid); "
        << "largest utilisation seen " << sci(r.max_utilisation, 3) << "; conversion KE change "
        << sci(r.kinetic_energy_change, 3) << " J\n";
    out << "  time: bonded " << sci(r.seconds_bonded, 4) << " s, rigid " << sci(r.seconds_rigid, 4)
        << " s, bridge " << sci(r.seconds_bridge, 4) << " s\n";
  }
  {
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
        << sci(median, 4) << " m (" << ext.size() << " pieces); L_c = " << sci(an.L_c, 4) << " m\n";
  }
  if (an.has_iso) {
    const auto& r = an.iso;
    out << "  ISO 19906 (h = " << sci(an.iso_in.thickness, 4) << " m, h_r = " << sci(max_pile, 4)
        << " m): H_B " << sci(r.H_B, 4) << ", H_P " << sci(r.H_P, 4) << ", H_R " << sci(r.H_R, 4) << ", H_L "
        << sci(r.H_L, 4) << ", H_T " << sci(r.H_T, 4) << " N\n";
    out << "  DEM peak horizontal force " << sci(st_peak_h, 4) << " N vs ISO F_H " << sci(r.F_H, 4)
        << " N: DEM/ISO = " << sci(r.F_H > 0 ? st_peak_h / r.F_H : 0.0, 3) << "\n";
  } else if (!iso_note.empty()) {
    out << "  " << iso_note << "\n";
  }
  if (comm.parallel())
    out << "  MPI: " << comm.size() << " ranks; force time max/mean " << sci(pf[0] / std::max(force_time_sum / comm.size(), 1e-12), 3)
        << " (load imbalance), max comm time " << sci(pf[1], 3) << " s (" << sci(100.0 * pf[1] / std::max(wall, 1e-9), 3)
        << " % of wall), " << e.parallel_stats().exchanges << " exchanges, " << migrated << " migrations, "
        << e.parallel_stats().balances << " load balances\n";
  if (comm.parallel()) {  // where the load balance put the cuts (they follow the busy region)
    const char* axis = "xyz";
    for (int a = 0; a < 3; ++a) {
      const auto& c = e.decomposition().cuts(a);
      if (c.size() <= 2) continue;
      out << "  cuts across " << axis[a] << " at";
      for (std::size_t k = 1; k + 1 < c.size(); ++k) out << " " << sci(c[k], 4);
      out << " m (structure at " << axis[a] << " = " << (has_st ? sci(e.mesh_wall_position(b.structure)[a], 4) : "-")
          << " m)\n";
    }
  }
  out << "  output: " << out_path << " (" << rows << " series rows, " << snaps << " snapshots)\n";
  return 0;
}

int iso_command(const RunOptions& opt, std::ostream& out) {
  nlohmann::json j = scene::read_json_file(opt.scene_path);
  analysis::IsoInputs in;
  if (j.is_object() && (j.contains("time") || j.contains("ice"))) {
    const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
    in = scene::iso_inputs(s, s.analysis.rubble_height);
  } else {
    if (!opt.overrides.empty())
      throw InputError("--set", "--set applies to scenes; edit the ISO object instead");
    in = analysis::iso_inputs_from_json(j, "");
  }
  const analysis::IsoResult r = analysis::compute_iso(in);
  nlohmann::json o = analysis::iso_to_json(r);
  o["inputs"] = analysis::iso_inputs_to_json(in);
  out << o.dump(2) << "\n";
  return 0;
}

}  // namespace hs::app

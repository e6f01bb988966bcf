// Ridge file: see ridge_file.h for the layout. HDF5 C API, through io/h5_handle.h.
#include "io/ridge_file.h"

#include "common/error.h"
#include "io/h5_handle.h"
#include "ridge/ridge_json.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

namespace hs::io {

using rigid::IceBox;
using rigid::RidgeBlock;
using rigid::RidgeJoint;
using rigid::RidgeProfile;
using rigid::RidgeResult;
using rigid::RidgeStats;
using rigid::ridge_def_from_json;
using rigid::ridge_def_to_json;
using rigid::ridge_report;

namespace {

constexpr const char* kFormat = "hybridsim-ridge/2";

using H = h5::Handle;

struct Ctx {
  std::string file;
  bool reading = false;
  [[noreturn]] void fail(const std::string& what, const std::string& obj) const {
    H5Eclear2(H5E_DEFAULT);
    if (reading) throw InputError(file, "not a readable ridge file: " + what + " failed for '" + obj + "'");
    throw std::runtime_error("HDF5 " + what + " failed for '" + obj + "' in '" + file + "'");
  }
  hid_t id(hid_t v, const char* what, const std::string& obj) const {
    if (v < 0) fail(what, obj);
    return v;
  }
  void ok(herr_t v, const char* what, const std::string& obj) const {
    if (v < 0) fail(what, obj);
  }
};

void write_str_attr(const Ctx& c, hid_t obj, const char* name, const std::string& text) {
  H type(c.id(H5Tcopy(H5T_C_S1), "H5Tcopy", name), H5Tclose);
  c.ok(H5Tset_size(type.get(), H5T_VARIABLE), "H5Tset_size", name);
  c.ok(H5Tset_cset(type.get(), H5T_CSET_UTF8), "H5Tset_cset", name);
  H space(c.id(H5Screate(H5S_SCALAR), "H5Screate", name), H5Sclose);
  H attr(c.id(H5Acreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), "H5Acreate2", name),
         H5Aclose);
  const char* p = text.c_str();
  c.ok(H5Awrite(attr.get(), type.get(), &p), "H5Awrite", name);
}

std::string read_str_attr(const Ctx& c, hid_t obj, const char* name) {
  if (H5Aexists(obj, name) <= 0) c.fail("attribute lookup", name);
  H attr(c.id(H5Aopen(obj, name, H5P_DEFAULT), "H5Aopen", name), H5Aclose);
  H type(c.id(H5Tcopy(H5T_C_S1), "H5Tcopy", name), H5Tclose);
  c.ok(H5Tset_size(type.get(), H5T_VARIABLE), "H5Tset_size", name);
  c.ok(H5Tset_cset(type.get(), H5T_CSET_UTF8), "H5Tset_cset", name);
  char* p = nullptr;
  c.ok(H5Aread(attr.get(), type.get(), &p), "H5Aread", name);
  std::string s = p ? p : "";
  if (p) H5free_memory(p);
  return s;
}

H group(const Ctx& c, hid_t parent, const char* name) {
  return H(c.id(H5Gcreate2(parent, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "H5Gcreate2", name),
           H5Gclose);
}

template <class T>
void write_ds(const Ctx& c, hid_t g, const char* name, const std::vector<T>& data, hsize_t rows, int width) {
  const hid_t mt = std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT32;
  const hid_t ft = std::is_same_v<T, double> ? H5T_IEEE_F64LE : H5T_STD_I32LE;
  hsize_t dims[2] = {rows, static_cast<hsize_t>(width)};
  H space(c.id(H5Screate_simple(width == 1 ? 1 : 2, dims, nullptr), "H5Screate_simple", name), H5Sclose);
  H ds(c.id(H5Dcreate2(g, name, ft, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "H5Dcreate2", name),
       H5Dclose);
  if (rows > 0) c.ok(H5Dwrite(ds.get(), mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), "H5Dwrite", name);
}

template <class T>
std::vector<T> read_ds(const Ctx& c, hid_t g, const char* name, int width, hsize_t& rows) {
  const hid_t mt = std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT32;
  if (H5Lexists(g, name, H5P_DEFAULT) <= 0) c.fail("dataset lookup", name);
  H ds(c.id(H5Dopen2(g, name, H5P_DEFAULT), "H5Dopen2", name), H5Dclose);
  H space(c.id(H5Dget_space(ds.get()), "H5Dget_space", name), H5Sclose);
  const int nd = H5Sget_simple_extent_ndims(space.get());
  hsize_t dims[2] = {0, 1};
  if (nd != (width == 1 ? 1 : 2)) c.fail("rank check", name);
  H5Sget_simple_extent_dims(space.get(), dims, nullptr);
  if (width > 1 && dims[1] != static_cast<hsize_t>(width)) c.fail("width check", name);
  rows = dims[0];
  std::vector<T> out(rows * width);
  if (rows > 0) c.ok(H5Dread(ds.get(), mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), "H5Dread", name);
  return out;
}

/// Every value of a dataset read from a ridge file must be finite (and > 0 where `positive`):
/// InputError naming the dataset, row and column, so a damaged or hand-edited file is refused
/// when it is read instead of crashing the run at its first step.
void check_values(const Ctx& c, const std::vector<double>& v, int width, const std::string& dataset,
                  bool positive = false) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double x = v[i];
    if (std::isfinite(x) && (!positive || x > 0)) continue;
    const std::size_t row = i / static_cast<std::size_t>(width), col = i % static_cast<std::size_t>(width);
    std::ostringstream os;
    os << x;
    throw InputError(c.file, "dataset " + dataset + " row " + std::to_string(row) +
                                 (width > 1 ? " column " + std::to_string(col) : std::string()) + " is " + os.str() +
                                 ": " + (positive ? "every value must be finite and > 0" : "every value must be finite") +
                                 "; the ridge file is damaged or was edited: regenerate it with `hybridsim ridge`");
  }
}

/// Rows of `width` values whose norm must be > 0 (orientations, joint normals).
void check_nonzero_rows(const Ctx& c, const std::vector<double>& v, int width, const std::string& dataset) {
  for (std::size_t i = 0; i + width <= v.size(); i += width) {
    double n2 = 0;
    for (int k = 0; k < width; ++k) n2 += v[i + k] * v[i + k];
    if (!(n2 > 1e-24))
      throw InputError(c.file, "dataset " + dataset + " row " + std::to_string(i / width) +
                                   " has zero length (a direction or rotation must not be zero); the ridge file is "
                                   "damaged or was edited: regenerate it with `hybridsim ridge`");
  }
}

void put3(std::vector<double>& v, const Vec3& x) { v.insert(v.end(), {x.x(), x.y(), x.z()}); }
Vec3 get3(const std::vector<double>& v, std::size_t i) { return Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]); }

nlohmann::json stats_json(const RidgeStats& s) {
  return {{"keel_blocks", s.keel_blocks}, {"sail_blocks", s.sail_blocks}, {"joints", s.joints},
          {"ice_joints", s.ice_joints}, {"keel_block_volume", s.keel_block_volume},
          {"sail_block_volume", s.sail_block_volume}, {"keel_target_volume", s.keel_target_volume},
          {"keel_porosity", s.keel_porosity}, {"core_porosity", s.core_porosity},
          {"keel_depth_target", s.keel_depth_target}, {"keel_depth_achieved", s.keel_depth_achieved},
          {"sail_height_target", s.sail_height_target}, {"sail_height_achieved", s.sail_height_achieved},
          {"keel_profile_rms_error", s.keel_profile_rms_error}, {"settle_time", s.settle_time}, {"compaction_time", s.compaction_time},
          {"settle_steps", s.settle_steps}, {"settled", s.settled},
          {"final_kinetic_energy_per_block", s.final_kinetic_energy_per_block},
          {"final_asleep_blocks", s.final_asleep_blocks},
          {"final_kinetic_energy_per_awake_block", s.final_kinetic_energy_per_awake_block},
          {"final_kinetic_energy_median", s.final_kinetic_energy_median},
          {"final_kinetic_energy_sail_fraction", s.final_kinetic_energy_sail_fraction},
          {"final_mean_displacement", s.final_mean_displacement},
          {"final_max_displacement", s.final_max_displacement},
          {"max_final_overlap", s.max_final_overlap}, {"wall_time", s.wall_time},
          {"block_net_buoyancy", s.block_net_buoyancy}, {"plate_net_buoyancy", s.plate_net_buoyancy}};
}

RidgeStats stats_from_json(const nlohmann::json& j) {
  RidgeStats s;
  s.keel_blocks = j.at("keel_blocks").get<std::size_t>();
  s.sail_blocks = j.at("sail_blocks").get<std::size_t>();
  s.joints = j.at("joints").get<std::size_t>();
  s.ice_joints = j.at("ice_joints").get<std::size_t>();
  s.keel_block_volume = j.at("keel_block_volume").get<double>();
  s.sail_block_volume = j.at("sail_block_volume").get<double>();
  s.keel_target_volume = j.at("keel_target_volume").get<double>();
  s.keel_porosity = j.at("keel_porosity").get<double>();
  s.core_porosity = j.at("core_porosity").get<double>();
  s.keel_depth_target = j.at("keel_depth_target").get<double>();
  s.keel_depth_achieved = j.at("keel_depth_achieved").get<double>();
  s.sail_height_target = j.at("sail_height_target").get<double>();
  s.sail_height_achieved = j.at("sail_height_achieved").get<double>();
  s.keel_profile_rms_error = j.at("keel_profile_rms_error").get<double>();
  s.settle_time = j.at("settle_time").get<double>();
  s.compaction_time = j.value("compaction_time", 0.0);  // absent in files before it existed
  s.settle_steps = j.at("settle_steps").get<std::uint64_t>();
  s.settled = j.at("settled").get<bool>();
  s.final_kinetic_energy_per_block = j.at("final_kinetic_energy_per_block").get<double>();
  s.max_final_overlap = j.at("max_final_overlap").get<double>();
  s.final_mean_displacement = j.value("final_mean_displacement", 0.0);
  s.final_max_displacement = j.value("final_max_displacement", 0.0);
  s.final_asleep_blocks = j.value("final_asleep_blocks", std::size_t{0});  // absent in older files
  s.final_kinetic_energy_per_awake_block = j.value("final_kinetic_energy_per_awake_block", 0.0);
  s.final_kinetic_energy_median = j.value("final_kinetic_energy_median", 0.0);
  s.final_kinetic_energy_sail_fraction = j.value("final_kinetic_energy_sail_fraction", 0.0);
  s.wall_time = j.at("wall_time").get<double>();
  s.block_net_buoyancy = j.at("block_net_buoyancy").get<double>();
  s.plate_net_buoyancy = j.at("plate_net_buoyancy").get<double>();
  return s;
}

}  // namespace

void save_ridge(const std::string& path, const RidgeResult& r) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Ctx c{path, false};
  H fapl(c.id(H5Pcreate(H5P_FILE_ACCESS), "H5Pcreate", "fapl"), H5Pclose);
  c.ok(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), "H5Pset_libver_bounds", "fapl");
  const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (f < 0) {
    H5Eclear2(H5E_DEFAULT);
    throw InputError(path, "cannot create the ridge file");
  }
  H file(f, H5Fclose);
  H root = group(c, file.get(), "ridge");
  write_str_attr(c, root.get(), "file_format", kFormat);
  write_str_attr(c, root.get(), "definition", ridge_def_to_json(r.def).dump());
  write_str_attr(c, root.get(), "stats", stats_json(r.stats).dump());
  write_str_attr(c, root.get(), "report", ridge_report(r).dump(2));
  write_str_attr(c, root.get(), "generation", rigid::ridge_generation_json(r).dump());

  {
    H g = group(c, root.get(), "blocks");
    std::vector<double> he, pos, q;
    std::vector<std::int32_t> part;
    for (const RidgeBlock& b : r.blocks) {
      put3(he, b.half_extents);
      put3(pos, b.position);
      q.insert(q.end(), {b.orientation.w(), b.orientation.x(), b.orientation.y(), b.orientation.z()});
      part.push_back(b.part);
    }
    const hsize_t n = r.blocks.size();
    write_ds(c, g.get(), "half_extents", he, n, 3);
    write_ds(c, g.get(), "position", pos, n, 3);
    write_ds(c, g.get(), "orientation", q, n, 4);
    write_ds(c, g.get(), "part", part, n, 1);
  }
  {
    H g = group(c, root.get(), "joints");
    std::vector<std::int32_t> ab;
    std::vector<double> anchor, normal, area;
    for (const RidgeJoint& j : r.joints) {
      ab.insert(ab.end(), {j.a, j.b});
      put3(anchor, j.anchor);
      put3(normal, j.normal);
      area.push_back(j.area);
    }
    const hsize_t m = r.joints.size();
    write_ds(c, g.get(), "blocks", ab, m, 2);
    write_ds(c, g.get(), "anchor", anchor, m, 3);
    write_ds(c, g.get(), "normal", normal, m, 3);
    write_ds(c, g.get(), "area", area, m, 1);
  }
  {
    H g = group(c, root.get(), "ice");
    std::vector<double> he, pos, lift;
    std::vector<std::int32_t> part;
    for (const IceBox& b : r.ice) {
      put3(he, b.half_extents);
      put3(pos, b.position);
      part.push_back(b.part);
      lift.push_back(b.lift);
    }
    const hsize_t k = r.ice.size();
    write_ds(c, g.get(), "half_extents", he, k, 3);
    write_ds(c, g.get(), "position", pos, k, 3);
    write_ds(c, g.get(), "part", part, k, 1);
    write_ds(c, g.get(), "lift", lift, k, 1);
  }
  {
    H g = group(c, root.get(), "profile");
    const RidgeProfile& p = r.profile;
    write_ds(c, g.get(), "x", p.x, p.x.size(), 1);
    write_ds(c, g.get(), "keel_target", p.keel_target, p.keel_target.size(), 1);
    write_ds(c, g.get(), "keel_depth", p.keel_depth, p.keel_depth.size(), 1);
    write_ds(c, g.get(), "sail_target", p.sail_target, p.sail_target.size(), 1);
    write_ds(c, g.get(), "sail_height", p.sail_height, p.sail_height.size(), 1);
  }
  c.ok(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), "H5Fflush", path);
}

namespace {

/// The generation's definition, statistics and record (the ice it settled under) from /ridge's
/// attributes.
void read_ridge_attributes(const Ctx& c, hid_t root, RidgeResult& r) {
  try {
    r.def = ridge_def_from_json(nlohmann::json::parse(read_str_attr(c, root, "definition")),
                                "/ridge@definition");
    r.stats = stats_from_json(nlohmann::json::parse(read_str_attr(c, root, "stats")));
    r.generation = read_str_attr(c, root, "generation");
    const nlohmann::json gen = nlohmann::json::parse(r.generation);
    const nlohmann::json& sh = gen.at("sheet");
    rigid::RidgeSheet& sheet = r.def.sheet;
    sheet.floating = sh.at("kind").get<std::string>() == "floating";
    sheet.consolidated_layer_center_x = gen.at("consolidated_layer").at("center_x").get<double>();
    if (sheet.floating) {
      sheet.particle_diameter = sh.at("particle_diameter").get<double>();
      sheet.plate_width = sh.at("plate_width").get<double>();
      sheet.plates_joined = sh.at("plates_joined").get<bool>();
      sheet.level_top = sh.at("level_ice").at("top_z").get<double>();
      sheet.level_underside = sh.at("level_ice").at("underside_z").get<double>();
      sheet.layer_top = sh.at("consolidated_layer").at("top_z").get<double>();
      sheet.layer_underside = sh.at("consolidated_layer").at("underside_z").get<double>();
      sheet.layer_width = sh.at("consolidated_layer").at("width").get<double>();
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(c.file, std::string("bad ridge attributes: ") + e.what());
  }
}

void read_ridge_blocks(const Ctx& c, hid_t root, RidgeResult& r) {
  hsize_t n = 0, t = 0;
  H g(c.id(H5Gopen2(root, "blocks", H5P_DEFAULT), "H5Gopen2", "/ridge/blocks"), H5Gclose);
  const auto he = read_ds<double>(c, g.get(), "half_extents", 3, n);
  const auto pos = read_ds<double>(c, g.get(), "position", 3, t);
  if (t != n) c.fail("row count check", "/ridge/blocks/position");
  const auto q = read_ds<double>(c, g.get(), "orientation", 4, t);
  if (t != n) c.fail("row count check", "/ridge/blocks/orientation");
  const auto part = read_ds<std::int32_t>(c, g.get(), "part", 1, t);
  if (t != n) c.fail("row count check", "/ridge/blocks/part");
  check_values(c, he, 3, "/ridge/blocks/half_extents", true);
  check_values(c, pos, 3, "/ridge/blocks/position");
  check_values(c, q, 4, "/ridge/blocks/orientation");
  check_nonzero_rows(c, q, 4, "/ridge/blocks/orientation");
  r.blocks.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    r.blocks[i].half_extents = get3(he, i);
    r.blocks[i].position = get3(pos, i);
    r.blocks[i].orientation = Quat(q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]);
    r.blocks[i].part = part[i];
  }

}

/// After the blocks: a joint's block indices are checked against them (the ice's in read_ridge_ice).
void read_ridge_joints(const Ctx& c, hid_t root, RidgeResult& r) {
  const hsize_t n = r.blocks.size();
  hsize_t m = 0, t = 0;
  H g(c.id(H5Gopen2(root, "joints", H5P_DEFAULT), "H5Gopen2", "/ridge/joints"), H5Gclose);
  const auto ab = read_ds<std::int32_t>(c, g.get(), "blocks", 2, m);
  const auto anchor = read_ds<double>(c, g.get(), "anchor", 3, t);
  if (t != m) c.fail("row count check", "/ridge/joints/anchor");
  const auto normal = read_ds<double>(c, g.get(), "normal", 3, t);
  if (t != m) c.fail("row count check", "/ridge/joints/normal");
  const auto area = read_ds<double>(c, g.get(), "area", 1, t);
  if (t != m) c.fail("row count check", "/ridge/joints/area");
  check_values(c, anchor, 3, "/ridge/joints/anchor");
  check_values(c, normal, 3, "/ridge/joints/normal");
  check_nonzero_rows(c, normal, 3, "/ridge/joints/normal");
  check_values(c, area, 1, "/ridge/joints/area", true);
  r.joints.resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    r.joints[i].a = ab[2 * i];
    r.joints[i].b = ab[2 * i + 1];
    r.joints[i].anchor = get3(anchor, i);
    r.joints[i].normal = get3(normal, i);
    r.joints[i].area = area[i];
    if (r.joints[i].a < 0 || static_cast<hsize_t>(r.joints[i].a) >= n ||
        static_cast<hsize_t>(std::max(r.joints[i].b, 0)) >= n)
      c.fail("joint index check", "/ridge/joints/blocks");
  }

}

void read_ridge_ice(const Ctx& c, hid_t root, RidgeResult& r) {
  hsize_t k = 0, t = 0;
  H g(c.id(H5Gopen2(root, "ice", H5P_DEFAULT), "H5Gopen2", "/ridge/ice"), H5Gclose);
  const auto he = read_ds<double>(c, g.get(), "half_extents", 3, k);
  const auto pos = read_ds<double>(c, g.get(), "position", 3, t);
  if (t != k) c.fail("row count check", "/ridge/ice/position");
  const auto part = read_ds<std::int32_t>(c, g.get(), "part", 1, t);
  if (t != k) c.fail("row count check", "/ridge/ice/part");
  const auto lift = read_ds<double>(c, g.get(), "lift", 1, t);
  if (t != k) c.fail("row count check", "/ridge/ice/lift");
  check_values(c, he, 3, "/ridge/ice/half_extents", true);
  check_values(c, pos, 3, "/ridge/ice/position");
  check_values(c, lift, 1, "/ridge/ice/lift");
  r.ice.resize(k);
  for (std::size_t i = 0; i < k; ++i) {
    r.ice[i].half_extents = get3(he, i);
    r.ice[i].position = get3(pos, i);
    r.ice[i].part = part[i];
    r.ice[i].lift = lift[i];
  }
  for (const RidgeJoint& j : r.joints)
    if (j.b < 0 && static_cast<hsize_t>(-1 - j.b) >= k) c.fail("joint ice index check", "/ridge/joints/blocks");

}

void read_ridge_profile(const Ctx& c, hid_t root, RidgeResult& r) {
  hsize_t t = 0;
  H g(c.id(H5Gopen2(root, "profile", H5P_DEFAULT), "H5Gopen2", "/ridge/profile"), H5Gclose);
  RidgeProfile& p = r.profile;
  p.x = read_ds<double>(c, g.get(), "x", 1, t);
  p.keel_target = read_ds<double>(c, g.get(), "keel_target", 1, t);
  p.keel_depth = read_ds<double>(c, g.get(), "keel_depth", 1, t);
  p.sail_target = read_ds<double>(c, g.get(), "sail_target", 1, t);
  p.sail_height = read_ds<double>(c, g.get(), "sail_height", 1, t);
  check_values(c, p.x, 1, "/ridge/profile/x");
  check_values(c, p.keel_target, 1, "/ridge/profile/keel_target");
  check_values(c, p.keel_depth, 1, "/ridge/profile/keel_depth");
  check_values(c, p.sail_target, 1, "/ridge/profile/sail_target");
  check_values(c, p.sail_height, 1, "/ridge/profile/sail_height");

}

}  // namespace

RidgeResult load_ridge(const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Ctx c{path, true};
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) {
    H5Eclear2(H5E_DEFAULT);
    throw InputError(path, "cannot open the ridge file (missing or not HDF5)");
  }
  H file(f, H5Fclose);
  if (H5Lexists(file.get(), "ridge", H5P_DEFAULT) <= 0) c.fail("group lookup", "/ridge");
  H root(c.id(H5Gopen2(file.get(), "ridge", H5P_DEFAULT), "H5Gopen2", "/ridge"), H5Gclose);
  const std::string fmt = read_str_attr(c, root.get(), "file_format");
  if (fmt == "hybridsim-ridge/1")
    throw InputError(path, "file_format is 'hybridsim-ridge/1': the ridge was made before ridge files recorded what "
                           "they were generated with (ice and water density, friction, the ice sheet; "
                           "docs/ridge.md, \"Generation record\"), so a run cannot check that its ice is the same; "
                           "regenerate it with `hybridsim ridge <scene>.json`");
  if (fmt != kFormat) throw InputError(path, "file_format is '" + fmt + "', expected '" + kFormat + "'");
  RidgeResult r;
  read_ridge_attributes(c, root.get(), r);
  read_ridge_blocks(c, root.get(), r);
  read_ridge_joints(c, root.get(), r);
  read_ridge_ice(c, root.get(), r);
  read_ridge_profile(c, root.get(), r);
  return r;
}

}  // namespace hs::io

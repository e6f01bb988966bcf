// Small meshes and helpers shared by the mesh tests.
#pragma once

#include "mesh/tri_mesh.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace hs::test {

/// A per-process scratch directory under the system temp dir for mesh fixtures,
/// removed when the test program exits.
inline std::filesystem::path mesh_tmp_dir() {
  struct Dir {
    std::filesystem::path path;
    Dir()
        : path(std::filesystem::temp_directory_path() /
               ("hybridsim_mesh_test_" + std::to_string(::getpid()))) {
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

inline std::string tmp_file(const std::string& name) { return (mesh_tmp_dir() / name).string(); }

inline std::string write_text(const std::string& name, const std::string& text) {
  const std::string path = tmp_file(name);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
  return path;
}

/// Axis-aligned closed box [lo, hi], 12 triangles, outward normals, one part "box".
inline mesh::TriMesh make_box(const Vec3& lo, const Vec3& hi) {
  mesh::TriMesh m;
  for (int k = 0; k < 8; ++k) {
    m.vertices.emplace_back((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(),
                            (k & 4) ? hi.z() : lo.z());
  }
  // Quads (counter-clockwise seen from outside), each split along its 0-2 diagonal.
  const std::uint32_t q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                 {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.triangles.push_back({f[0], f[1], f[2]});
    m.triangles.push_back({f[0], f[2], f[3]});
  }
  m.triangle_part.assign(m.triangles.size(), 0);
  m.part_names = {"box"};
  mesh::build_topology(m);
  return m;
}

/// Flat open mesh in the plane z = 0 (normal +z): a regular fan of `n` triangles
/// around the origin with outer radius `radius`.
inline mesh::TriMesh make_fan(int n, double radius) {
  mesh::TriMesh m;
  m.vertices.emplace_back(0.0, 0.0, 0.0);
  for (int k = 0; k < n; ++k) {
    const double a = 2.0 * kPi * k / n;
    m.vertices.emplace_back(radius * std::cos(a), radius * std::sin(a), 0.0);
  }
  for (int k = 0; k < n; ++k) {
    m.triangles.push_back({0, std::uint32_t(1 + k), std::uint32_t(1 + (k + 1) % n)});
  }
  m.triangle_part.assign(m.triangles.size(), 0);
  m.part_names = {"fan"};
  mesh::build_topology(m);
  return m;
}

/// Two coplanar triangles in z = 0 sharing the edge (0,0,0)-(1,1,0): the unit square.
inline mesh::TriMesh make_square() {
  mesh::TriMesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  m.triangle_part = {0, 0};
  m.part_names = {"square"};
  mesh::build_topology(m);
  return m;
}

}  // namespace hs::test

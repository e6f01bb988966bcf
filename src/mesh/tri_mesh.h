// Triangle meshes for structures (bridge piers, walls): storage, topology, file I/O.
//
// Conventions (see scenes/meshes/README.md): metres, z up, water line at z = 0,
// triangles wound counter-clockwise seen from outside, so the right-hand normal
// (b - a) x (c - a) points out of the solid.
//
// Topology is built once (build_topology) so that every contact feature has a stable id:
//   face id   = triangle index,
//   edge id   = index into `edges` (unique undirected edges, sorted by vertex pair),
//   vertex id = index into `vertices`.
// Loaders merge coincident vertices ("welding"; STL stores every triangle's corners
// separately) so neighbouring triangles share edges and vertices.
#pragma once

#include "common/types.h"

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace hs::mesh {

inline constexpr std::uint32_t kNoTriangle = 0xFFFFFFFFu;

struct Aabb {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
  void extend(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  bool empty() const { return !(lo.array() <= hi.array()).all(); }
  Vec3 extent() const { return hi - lo; }
};

struct TriMesh {
  // ---- geometry (filled by a loader or a generator) ----
  std::vector<Vec3> vertices;                              ///< m
  std::vector<std::array<std::uint32_t, 3>> triangles;     ///< CCW seen from outside
  std::vector<std::uint16_t> triangle_part;                ///< index into part_names
  std::vector<std::string> part_names;                     ///< e.g. "neck", "cone", "shaft"

  // ---- topology (build_topology) ----
  /// Unique undirected edges; edges[e] = {v0, v1} with v0 < v1, sorted lexicographically.
  std::vector<std::array<std::uint32_t, 2>> edges;
  /// triangle_edges[t][i] = edge id of side i, from triangles[t][i] to triangles[t][(i+1)%3].
  std::vector<std::array<std::uint32_t, 3>> triangle_edges;
  /// First two triangles using each edge (kNoTriangle where there is none).
  std::vector<std::array<std::uint32_t, 2>> edge_triangles;
  /// Number of triangles using each edge (2 everywhere on a closed manifold mesh).
  std::vector<std::uint32_t> edge_triangle_count;
  /// Vertex -> incident edge ids, CSR: edges of vertex v are
  /// vertex_edges[vertex_edge_offsets[v] .. vertex_edge_offsets[v+1]).
  std::vector<std::uint32_t> vertex_edge_offsets;
  std::vector<std::uint32_t> vertex_edges;

  bool has_topology() const {
    return triangle_edges.size() == triangles.size() &&
           vertex_edge_offsets.size() == vertices.size() + 1;
  }
};

/// (Re)builds the edge/vertex topology. Deterministic: ids depend only on the geometry
/// arrays. Call after any change to `vertices` or `triangles`.
void build_topology(TriMesh& mesh);

/// Merges vertices closer than `tolerance` (m), remaps triangles, drops unused vertices.
/// Vertex order follows first use. Does not build the topology.
void weld_vertices(TriMesh& mesh, double tolerance);

/// Checks the mesh is usable: at least one triangle, finite vertices, indices in range,
/// part ids in range, no zero-area triangles. Throws hs::InputError(source, ...) naming
/// the triangle/vertex and the fix. `source` is the file name (or a scene path).
void validate_mesh(const TriMesh& mesh, const std::string& source);

Aabb bounding_box(const TriMesh& mesh);

/// Every edge is used by exactly two triangles (watertight, manifold edges).
bool is_closed(const TriMesh& mesh);

/// Every edge shared by two triangles is traversed in opposite directions by them
/// (consistent winding). Together with is_closed and signed_volume > 0 this means
/// all normals point outwards.
bool is_consistently_oriented(const TriMesh& mesh);

/// Signed enclosed volume (divergence theorem, m^3); positive for a closed mesh with
/// outward normals. Meaningless for an open mesh.
double signed_volume(const TriMesh& mesh);

/// Unit outward normal of triangle t ((b - a) x (c - a), normalised).
Vec3 triangle_normal(const TriMesh& mesh, std::uint32_t t);

// ---- file I/O ----

struct MeshLoadOptions {
  /// Vertices closer than this are merged (m). Negative: 1e-6 times the bounding-box
  /// diagonal. 0: merge only bit-identical positions.
  double weld_tolerance = -1.0;
};

/// STL, ASCII or binary (binary when the size is exactly 84 + 50*n for the n in its
/// header). ASCII files make one part per `solid <name>`; binary files one part named
/// after the file stem. Vertices are welded, the mesh validated, topology built.
TriMesh load_stl(const std::string& path, const MeshLoadOptions& options = {});

/// Wavefront OBJ: `v` and `f` lines (f entries may be i, i/t, i//n, i/t/n; negative
/// indices count back from the last vertex read); polygons are fan-triangulated;
/// `g` and `o` lines start a named part (faces before any are in a part named after
/// the file stem). Other statements are ignored. Welded, validated, topology built.
TriMesh load_obj(const std::string& path, const MeshLoadOptions& options = {});

/// By extension (.stl / .obj, case-insensitive); InputError otherwise.
TriMesh load_mesh(const std::string& path, const MeshLoadOptions& options = {});

/// Binary STL (little-endian, float32: ~7 significant digits, so coordinates of a
/// 10 m pier round by ~1e-6 m). Parts are not stored.
void write_stl_binary(const TriMesh& mesh, const std::string& path);

/// ASCII STL with 17 significant digits (doubles round-trip exactly); one `solid` per
/// part, so load_stl recovers the part names.
void write_stl_ascii(const TriMesh& mesh, const std::string& path);

}  // namespace hs::mesh

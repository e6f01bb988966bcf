// Sphere - triangle-mesh contact geometry, with no double counting across shared
// edges and vertices.
//
// For a sphere (centre c, radius r) the query returns every point q of the mesh
// surface that is a LOCAL MINIMUM of the distance |c - q| with |c - q| < r, one contact
// per mesh feature (face, edge or vertex) carrying that point:
//   overlap = r - |c - q|,  normal = (c - q)/|c - q|  (unit, from the surface to the
//   centre), point = q.
// A face contact uses the signed plane distance d = (c - a).n_face instead, with
// normal = n_face and overlap = r - d (exactly the analytic plane).
// Sides (applied to the candidates before the merge steps 2-4 below): on a CLOSED mesh
// contacts are one-sided. Each candidate is classed front or
// back: a face by the sign of d, an edge or vertex by the sign of (c - q).N with N its
// angle-weighted pseudo-normal (Baerentzen & Aanaes 2005: exact inside/outside test for
// the closest point). The nearest candidate decides where the centre is:
//   outside -> back-facing candidates are dropped (they are the far side of a part of
//              the solid thinner than r, e.g. the annulus seen through the sharp cone
//              rim);
//   inside  -> (a centre less than r deep: it went through the surface) only the nearest
//              contact is returned, pushing out: normal = n_face (overlap r - d > r) or
//              -(c - q)/|c - q| (overlap r + |c - q|).
// A centre deeper than r inside the solid is not seen. On an OPEN mesh (a plate)
// contacts are two-sided: the normal points to whichever side the centre is.
// Summing a force law over the contacts therefore gives, for a sphere touching one
// convex feature, exactly the force of the analytic plane, line or point, and for a
// sphere in a concave corner one contact per wall it touches.
//
// Algorithm (per candidate triangle, then a merge):
//  1. Closest point on the triangle with feature classification: the centre's
//     projection lies inside the triangle by more than `tol` from every side -> Face;
//     otherwise the closest point on the three sides -> Edge, or Vertex when it is
//     within `tol` of a corner. (tol = 1e-10 x mesh bounding-box diagonal makes the
//     classification of a centre exactly above a shared edge or vertex the same in every
//     triangle that shares it, whatever the rounding.)
//  2. Edge contacts are deduplicated by edge id and vertex contacts by vertex id (each
//     triangle sharing the feature finds the same point).
//  3. An edge contact is dropped if a triangle containing the edge already has a face
//     contact, and a vertex contact if an edge or a face containing the vertex already
//     has a contact. Why: the centre then projects into that face (or onto that edge),
//     so the edge/vertex point is not the closest point of the surface but the same
//     material contact seen from a neighbouring triangle; keeping it would count a
//     sphere resting on a face next to a convex edge twice.
//  4. Rule 3 alone misses one case: above a fan of coplanar triangles, a centre over
//     triangle A near the shared vertex is within r of an edge of a NON-adjacent
//     triangle B (an edge that does not touch A). So an edge contact is also dropped
//     unless, for each triangle T containing the edge, (c - q).u_T <= 2 tol (u_T: unit
//     in-plane normal of the edge pointing into T; the centre must not project past the
//     edge into T), and a vertex contact unless (c - v).(w - v) <= 2 tol |w - v| for
//     every edge (v, w) at the vertex. These are exactly the conditions for q to be a
//     local minimum of the distance (step 3 is the special case where T itself is in
//     contact); the 2 tol vs tol margin means a point is never dropped by both the face
//     test of step 1 and the edge test here, so no contact is lost at the boundaries.
//
// Moving meshes: the mesh is stored in its own (local) frame and may be moved rigidly by
// a translation `offset`. The query takes the sphere centre in mesh-local coordinates,
// i.e. the caller passes (x_world - offset); the returned `point` is mesh-local (add
// `offset` back for world coordinates); normals and overlaps are frame-independent.
//
// Cost: the query allocates nothing once `out` and `scratch` have grown (the first query
// sizes the scratch's per-triangle visit stamps; then only a new largest contact count
// can grow them). Reuse them across particles; one scratch per thread. MeshGrid is
// immutable after construction and can be queried from many threads at once.
// Measured: ~120 ns per query (default pier, r = 0.25 m, particles within 3 m of it,
// -O3, one core of the dev box).
#pragma once

#include "mesh/tri_mesh.h"

#include <cstdint>
#include <vector>

namespace hs::mesh {

struct MeshContact {
  enum Feature : std::uint8_t { Face = 0, Edge = 1, Vertex = 2 };

  Vec3 point;             ///< closest surface point, mesh-local, m
  Vec3 normal;            ///< unit, from the mesh surface towards the sphere centre
  double overlap;         ///< r - distance, m (> 0)
  std::uint32_t triangle; ///< a triangle carrying the feature (the first one found)
  std::uint16_t part;     ///< part of `triangle` (index into TriMesh::part_names)
  Feature feature;
  std::uint32_t feature_id;  ///< triangle id, edge id or vertex id (see TriMesh)
};

/// Per-thread scratch for MeshGrid::query (candidate contacts before the merge).
struct MeshQueryScratch {
  std::vector<MeshContact> candidates;
  std::vector<std::uint32_t> visit_stamp;  ///< per triangle: last query that visited it
  std::uint32_t stamp = 0;
};

/// Uniform grid over the triangles (each listed in the cells of its bounding box that
/// its plane passes through) plus the per-triangle data the
/// closest-point test needs (unit normal, in-plane side normals, side lengths), built
/// once per mesh.
class MeshGrid {
 public:
  /// `max_query_radius` (m) sets the cell size (2 x radius, so a query touches at most
  /// 2 x 2 x 2 cells); larger radii still work, they just visit more cells. The cell
  /// size is enlarged when needed to keep the grid under ~4 M cells and ~32 M entries.
  /// Builds the mesh topology if it is missing. Throws hs::InputError if the mesh is
  /// invalid (validate_mesh) or max_query_radius is not > 0.
  MeshGrid(TriMesh mesh, double max_query_radius);

  /// All contacts of the sphere (centre in mesh-local coordinates, radius > 0), merged
  /// as described above. Clears `out` first; returns out.size(). Deterministic: the
  /// order depends only on the mesh, the grid and the inputs.
  std::size_t query(const Vec3& centre_local, double radius, std::vector<MeshContact>& out,
                    MeshQueryScratch& scratch) const;

  const TriMesh& mesh() const { return mesh_; }
  const Aabb& bounds() const { return bounds_; }
  double cell_size() const { return h_; }
  /// Feature classification tolerance `tol`, m.
  double tolerance() const { return tol_; }
  /// One-sided (closed mesh) or two-sided (open mesh) face contacts.
  bool two_sided() const { return two_sided_; }

 private:
  // Cheap culling data, touched for every candidate (80 bytes).
  struct TriCull {
    Vec3 normal;     // unit outward normal
    double offset;   // normal . a
    Vec3 lo, hi;     // bounding box
  };
  // Closest-point data, touched only for triangles within r of the sphere's plane.
  struct TriData {
    Vec3 v[3];                 // corners
    Vec3 side_normal[3];       // unit, in-plane, perpendicular to side i, into the triangle
    double len[3];             // side lengths
    double inv_len2[3];        // 1 / len^2
    std::uint32_t vertex[3];   // vertex ids
    std::uint32_t edge[3];     // edge id of side i (v[i] -> v[(i+1)%3])
    std::uint16_t part;
  };

  void collect(const Vec3& c, double r, std::vector<MeshContact>& cand,
               std::vector<std::uint32_t>& stamps, std::uint32_t& stamp) const;
  void push_point_contact(const Vec3& c, double r, const Vec3& q, const Vec3& pseudo_normal,
                          std::uint32_t t, MeshContact::Feature f, std::uint32_t id,
                          std::vector<MeshContact>& cand) const;
  bool edge_is_local_minimum(const Vec3& c, std::uint32_t edge) const;
  bool vertex_is_local_minimum(const Vec3& c, std::uint32_t vertex) const;

  TriMesh mesh_;
  std::vector<TriCull> cull_;
  std::vector<TriData> data_;
  std::vector<Vec3> edge_pseudo_normal_;    // n_A + n_B (unnormalised)
  std::vector<Vec3> vertex_pseudo_normal_;  // sum of incident angle x n_T (unnormalised)
  Aabb bounds_;
  double h_ = 0.0;
  double inv_h_ = 0.0;
  double tol_ = 0.0;
  bool two_sided_ = false;
  std::int32_t dims_[3] = {1, 1, 1};
  std::vector<std::uint32_t> cell_start_;  // CSR over cells (x fastest)
  std::vector<std::uint32_t> cell_tris_;
};

}  // namespace hs::mesh

#include "mesh/sphere_mesh_contact.h"

#include "common/error.h"

#include <algorithm>
#include <cmath>

namespace hs::mesh {

namespace {

constexpr double kMaxCells = 4.0e6;
constexpr double kMaxEntries = 32.0e6;

}  // namespace

MeshGrid::MeshGrid(TriMesh mesh, double max_query_radius) : mesh_(std::move(mesh)) {
  if (!(max_query_radius > 0.0) || !std::isfinite(max_query_radius)) {
    throw InputError("max_query_radius", "must be a finite radius > 0 m (the largest particle "
                                         "radius that will touch the mesh)");
  }
  validate_mesh(mesh_, "mesh");
  if (!mesh_.has_topology()) build_topology(mesh_);
  two_sided_ = !is_closed(mesh_);

  bounds_ = bounding_box(mesh_);
  const double diag = bounds_.extent().norm();
  tol_ = 1e-10 * diag;
  bounds_.lo.array() -= tol_;
  bounds_.hi.array() += tol_;

  const std::size_t nt = mesh_.triangles.size();
  cull_.resize(nt);
  data_.resize(nt);
  edge_pseudo_normal_.assign(mesh_.edges.size(), Vec3::Zero());
  vertex_pseudo_normal_.assign(mesh_.vertices.size(), Vec3::Zero());
  for (std::size_t t = 0; t < nt; ++t) {
    const auto& tri = mesh_.triangles[t];
    TriData& d = data_[t];
    TriCull& c = cull_[t];
    for (int i = 0; i < 3; ++i) {
      d.v[i] = mesh_.vertices[tri[i]];
      d.vertex[i] = tri[i];
      d.edge[i] = mesh_.triangle_edges[t][i];
    }
    const Vec3 n = (d.v[1] - d.v[0]).cross(d.v[2] - d.v[0]).normalized();
    for (int i = 0; i < 3; ++i) {
      const Vec3 e = d.v[(i + 1) % 3] - d.v[i];
      d.len[i] = e.norm();
      d.inv_len2[i] = 1.0 / e.squaredNorm();
      d.side_normal[i] = n.cross(e) / d.len[i];
      edge_pseudo_normal_[d.edge[i]] += n;
      // Interior angle at corner i.
      const Vec3 a = d.v[(i + 1) % 3] - d.v[i];
      const Vec3 b = d.v[(i + 2) % 3] - d.v[i];
      vertex_pseudo_normal_[tri[i]] += std::atan2(a.cross(b).norm(), a.dot(b)) * n;
    }
    d.part = mesh_.triangle_part[t];
    c.normal = n;
    c.offset = n.dot(d.v[0]);
    c.lo = d.v[0].cwiseMin(d.v[1]).cwiseMin(d.v[2]);
    c.hi = d.v[0].cwiseMax(d.v[1]).cwiseMax(d.v[2]);
  }

  // Cell size: 2 x the query radius, enlarged until the grid stays within budget.
  const Vec3 ext = bounds_.extent();
  h_ = std::max(2.0 * max_query_radius, 1e-6 * diag);
  for (;;) {
    inv_h_ = 1.0 / h_;
    double cells = 1.0;
    for (int a = 0; a < 3; ++a) {
      dims_[a] = std::int32_t(std::floor(ext[a] * inv_h_)) + 1;
      cells *= dims_[a];
    }
    double entries = 0.0;
    for (const auto& c : cull_) {
      double k = 1.0;
      for (int a = 0; a < 3; ++a) k *= std::floor((c.hi[a] - c.lo[a]) * inv_h_) + 2.0;
      entries += k;
    }
    if (cells <= kMaxCells && entries <= kMaxEntries) break;
    h_ *= 1.5;
  }

  auto cell_of = [&](double x, int a) {
    const double f = std::floor((x - bounds_.lo[a]) * inv_h_);
    return std::int32_t(std::clamp(f, 0.0, double(dims_[a] - 1)));
  };
  const std::size_t ncells = std::size_t(dims_[0]) * dims_[1] * dims_[2];
  cell_start_.assign(ncells + 1, 0);
  // Cells of the triangle's bounding box that its plane passes through (a plane-box
  // separating-axis test, padded): long slanted triangles skip most of their box.
  auto for_cells = [&](std::size_t t, auto&& f) {
    const TriCull& c = cull_[t];
    std::int32_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = cell_of(c.lo[a], a);
      hi[a] = cell_of(c.hi[a], a);
    }
    const double reach = 0.5 * h_ * c.normal.cwiseAbs().sum() + 4.0 * tol_;
    for (std::int32_t z = lo[2]; z <= hi[2]; ++z)
      for (std::int32_t y = lo[1]; y <= hi[1]; ++y)
        for (std::int32_t x = lo[0]; x <= hi[0]; ++x) {
          const Vec3 centre = bounds_.lo + h_ * Vec3(x + 0.5, y + 0.5, z + 0.5);
          if (std::abs(c.normal.dot(centre) - c.offset) > reach) continue;
          f((std::size_t(z) * dims_[1] + y) * dims_[0] + x);
        }
  };
  for (std::size_t t = 0; t < nt; ++t) {
    for_cells(t, [&](std::size_t cell) { ++cell_start_[cell + 1]; });
  }
  for (std::size_t i = 0; i < ncells; ++i) cell_start_[i + 1] += cell_start_[i];
  cell_tris_.resize(cell_start_[ncells]);
  std::vector<std::uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t t = 0; t < nt; ++t) {
    for_cells(t, [&](std::size_t cell) { cell_tris_[fill[cell]++] = std::uint32_t(t); });
  }
}

void MeshGrid::push_point_contact(const Vec3& c, double r, const Vec3& q,
                                  const Vec3& pseudo_normal, std::uint32_t t,
                                  MeshContact::Feature f, std::uint32_t id,
                                  std::vector<MeshContact>& cand) const {
  const Vec3 dv = c - q;
  const double dist = dv.norm();
  MeshContact k;
  k.point = q;
  k.triangle = t;
  k.part = data_[t].part;
  k.feature = f;
  k.feature_id = id;
  if (dist > 0.0) {
    if (!two_sided_ && dv.dot(pseudo_normal) < 0.0) {
      k.normal = -dv / dist;  // centre inside the solid: push it back out
      k.overlap = r + dist;
    } else {
      k.normal = dv / dist;
      k.overlap = r - dist;
    }
  } else {
    k.normal = pseudo_normal.normalized();
    k.overlap = r;
  }
  cand.push_back(k);
}

void MeshGrid::collect(const Vec3& c, double r, std::vector<MeshContact>& cand,
                       std::vector<std::uint32_t>& stamps, std::uint32_t& stamp) const {
  const Vec3 qlo = c.array() - r;
  const Vec3 qhi = c.array() + r;
  if ((qhi.array() < bounds_.lo.array()).any() || (qlo.array() > bounds_.hi.array()).any()) {
    return;
  }
  std::int32_t ilo[3], ihi[3];
  for (int a = 0; a < 3; ++a) {
    const double flo = std::floor((qlo[a] - bounds_.lo[a]) * inv_h_);
    const double fhi = std::floor((qhi[a] - bounds_.lo[a]) * inv_h_);
    ilo[a] = std::int32_t(std::clamp(flo, 0.0, double(dims_[a] - 1)));
    ihi[a] = std::int32_t(std::clamp(fhi, 0.0, double(dims_[a] - 1)));
  }
  const double r2 = r * r;
  const double tol = tol_;
  // Visit each triangle once per query (a triangle spans several cells).
  if (stamps.size() < cull_.size()) {
    stamps.assign(cull_.size(), 0);
    stamp = 0;
  }
  if (++stamp == 0) {
    std::fill(stamps.begin(), stamps.end(), 0);
    stamp = 1;
  }

  for (std::int32_t iz = ilo[2]; iz <= ihi[2]; ++iz) {
    for (std::int32_t iy = ilo[1]; iy <= ihi[1]; ++iy) {
      for (std::int32_t ix = ilo[0]; ix <= ihi[0]; ++ix) {
        const std::size_t cell = (std::size_t(iz) * dims_[1] + iy) * dims_[0] + ix;
        for (std::uint32_t k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) {
          const std::uint32_t t = cell_tris_[k];
          if (stamps[t] == stamp) continue;
          stamps[t] = stamp;
          const TriCull& tc = cull_[t];
          if ((tc.lo.array() > qhi.array()).any() || (tc.hi.array() < qlo.array()).any()) {
            continue;
          }
          const double d = tc.normal.dot(c) - tc.offset;  // signed height above the plane
          if (d >= r || d <= -r) continue;

          const TriData& td = data_[t];
          double s[3];
          for (int i = 0; i < 3; ++i) s[i] = (c - td.v[i]).dot(td.side_normal[i]);
          if (s[0] > tol && s[1] > tol && s[2] > tol) {
            MeshContact f;
            f.point = c - d * tc.normal;
            if (two_sided_ && d < 0.0) {
              f.normal = -tc.normal;
              f.overlap = r + d;
            } else {
              f.normal = tc.normal;
              f.overlap = r - d;
            }
            f.triangle = t;
            f.part = td.part;
            f.feature = MeshContact::Face;
            f.feature_id = t;
            cand.push_back(f);
            continue;
          }

          // Closest point on the sides the projection is outside of (or within tol of).
          double best_d2 = r2;
          int best_i = -1;
          double best_t = 0.0;
          for (int i = 0; i < 3; ++i) {
            if (s[i] > tol) continue;
            const int j = i == 2 ? 0 : i + 1;
            const Vec3 e = td.v[j] - td.v[i];
            const double u = std::clamp((c - td.v[i]).dot(e) * td.inv_len2[i], 0.0, 1.0);
            const double d2 = (c - (td.v[i] + u * e)).squaredNorm();
            if (d2 < best_d2) {
              best_d2 = d2;
              best_i = i;
              best_t = u;
            }
          }
          if (best_i < 0) continue;  // nothing within r
          const int i = best_i;
          const int j = i == 2 ? 0 : i + 1;
          const double along = best_t * td.len[i];
          if (along <= tol) {
            push_point_contact(c, r, td.v[i], vertex_pseudo_normal_[td.vertex[i]], t,
                               MeshContact::Vertex, td.vertex[i], cand);
          } else if (along >= td.len[i] - tol) {
            push_point_contact(c, r, td.v[j], vertex_pseudo_normal_[td.vertex[j]], t,
                               MeshContact::Vertex, td.vertex[j], cand);
          } else {
            push_point_contact(c, r, td.v[i] + best_t * (td.v[j] - td.v[i]),
                               edge_pseudo_normal_[td.edge[i]], t, MeshContact::Edge, td.edge[i],
                               cand);
          }
        }
      }
    }
  }
}

bool MeshGrid::edge_is_local_minimum(const Vec3& c, std::uint32_t edge) const {
  for (const std::uint32_t t : mesh_.edge_triangles[edge]) {
    if (t == kNoTriangle) continue;
    const TriData& td = data_[t];
    for (int i = 0; i < 3; ++i) {
      if (td.edge[i] == edge && (c - td.v[i]).dot(td.side_normal[i]) > 2.0 * tol_) return false;
    }
  }
  return true;
}

bool MeshGrid::vertex_is_local_minimum(const Vec3& c, std::uint32_t v) const {
  const Vec3& p = mesh_.vertices[v];
  const Vec3 cp = c - p;
  for (std::uint32_t k = mesh_.vertex_edge_offsets[v]; k < mesh_.vertex_edge_offsets[v + 1]; ++k) {
    const auto& e = mesh_.edges[mesh_.vertex_edges[k]];
    const Vec3 dir = mesh_.vertices[e[0] == v ? e[1] : e[0]] - p;
    if (cp.dot(dir) > 2.0 * tol_ * dir.norm()) return false;
  }
  return true;
}

std::size_t MeshGrid::query(const Vec3& c, double r, std::vector<MeshContact>& out,
                            MeshQueryScratch& scratch) const {
  out.clear();
  auto& cand = scratch.candidates;
  cand.clear();
  collect(c, r, cand, scratch.visit_stamp, scratch.stamp);
  if (cand.empty()) return 0;

  if (!two_sided_) {
    // Inside or outside, from the nearest candidate: its sign (face normal or
    // pseudo-normal) is exact for the closest point. Back-facing candidates have
    // overlap > r.
    std::size_t nearest = 0;
    double nearest_dist = std::abs(cand[0].overlap - r);
    for (std::size_t i = 1; i < cand.size(); ++i) {
      const double d = std::abs(cand[i].overlap - r);
      if (d < nearest_dist) {
        nearest = i;
        nearest_dist = d;
      }
    }
    if (cand[nearest].overlap > r) {
      // Centre inside the solid (less than r deep): push out along the shortest way.
      out.push_back(cand[nearest]);
      return 1;
    }
    // Outside: a back-facing candidate is the far side of a part of the solid thinner
    // than r (e.g. the annulus seen through the sharp cone rim), not a contact.
    cand.erase(std::remove_if(cand.begin(), cand.end(),
                              [r](const MeshContact& k) { return k.overlap > r; }),
               cand.end());
  }

  auto face_contains_edge = [&](std::uint32_t e) {
    for (const auto& k : cand) {
      if (k.feature != MeshContact::Face) continue;
      const auto& te = data_[k.triangle].edge;
      if (te[0] == e || te[1] == e || te[2] == e) return true;
    }
    return false;
  };
  auto feature_contains_vertex = [&](std::uint32_t v) {
    for (const auto& k : cand) {
      if (k.feature == MeshContact::Face) {
        const auto& tv = data_[k.triangle].vertex;
        if (tv[0] == v || tv[1] == v || tv[2] == v) return true;
      } else if (k.feature == MeshContact::Edge) {
        const auto& ev = mesh_.edges[k.feature_id];
        if (ev[0] == v || ev[1] == v) return true;
      }
    }
    return false;
  };
  auto already_out = [&](MeshContact::Feature f, std::uint32_t id) {
    for (const auto& k : out) {
      if (k.feature == f && k.feature_id == id) return true;
    }
    return false;
  };

  for (const auto& k : cand) {
    switch (k.feature) {
      case MeshContact::Face:
        out.push_back(k);
        break;
      case MeshContact::Edge:
        if (already_out(MeshContact::Edge, k.feature_id) || face_contains_edge(k.feature_id) ||
            !edge_is_local_minimum(c, k.feature_id)) {
          break;
        }
        out.push_back(k);
        break;
      case MeshContact::Vertex:
        if (already_out(MeshContact::Vertex, k.feature_id) ||
            feature_contains_vertex(k.feature_id) || !vertex_is_local_minimum(c, k.feature_id)) {
          break;
        }
        out.push_back(k);
        break;
    }
  }
  return out.size();
}

}  // namespace hs::mesh

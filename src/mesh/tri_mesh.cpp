#include "mesh/tri_mesh.h"

#include "common/error.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>
#include <unordered_map>

namespace hs::mesh {

static_assert(std::endian::native == std::endian::little,
              "binary STL I/O assumes a little-endian host");

// ------------------------------------------------------------------------------------
// topology
// ------------------------------------------------------------------------------------

void build_topology(TriMesh& m) {
  const std::size_t nt = m.triangles.size();
  struct Side {
    std::uint64_t key;   // (min vertex << 32) | max vertex
    std::uint32_t side;  // 3 * triangle + i
  };
  std::vector<Side> sides;
  sides.reserve(3 * nt);
  for (std::size_t t = 0; t < nt; ++t) {
    for (int i = 0; i < 3; ++i) {
      const std::uint32_t a = m.triangles[t][i];
      const std::uint32_t b = m.triangles[t][(i + 1) % 3];
      const std::uint64_t key =
          (std::uint64_t(std::min(a, b)) << 32) | std::uint64_t(std::max(a, b));
      sides.push_back({key, std::uint32_t(3 * t + i)});
    }
  }
  std::sort(sides.begin(), sides.end(), [](const Side& x, const Side& y) {
    return x.key != y.key ? x.key < y.key : x.side < y.side;
  });

  m.edges.clear();
  m.edge_triangles.clear();
  m.edge_triangle_count.clear();
  m.triangle_edges.assign(nt, {0, 0, 0});
  for (std::size_t s = 0; s < sides.size(); ++s) {
    if (s == 0 || sides[s].key != sides[s - 1].key) {
      m.edges.push_back({std::uint32_t(sides[s].key >> 32), std::uint32_t(sides[s].key)});
      m.edge_triangles.push_back({kNoTriangle, kNoTriangle});
      m.edge_triangle_count.push_back(0);
    }
    const std::uint32_t e = std::uint32_t(m.edges.size() - 1);
    const std::uint32_t t = sides[s].side / 3;
    m.triangle_edges[t][sides[s].side % 3] = e;
    auto& et = m.edge_triangles[e];
    if (et[0] == kNoTriangle) {
      et[0] = t;
    } else if (et[1] == kNoTriangle && et[0] != t) {
      et[1] = t;
    }
    ++m.edge_triangle_count[e];
  }

  const std::size_t nv = m.vertices.size();
  m.vertex_edge_offsets.assign(nv + 1, 0);
  for (const auto& e : m.edges) {
    ++m.vertex_edge_offsets[e[0] + 1];
    ++m.vertex_edge_offsets[e[1] + 1];
  }
  for (std::size_t v = 0; v < nv; ++v) m.vertex_edge_offsets[v + 1] += m.vertex_edge_offsets[v];
  m.vertex_edges.assign(m.vertex_edge_offsets[nv], 0);
  std::vector<std::uint32_t> fill(m.vertex_edge_offsets.begin(), m.vertex_edge_offsets.end() - 1);
  for (std::uint32_t e = 0; e < m.edges.size(); ++e) {
    m.vertex_edges[fill[m.edges[e][0]]++] = e;
    m.vertex_edges[fill[m.edges[e][1]]++] = e;
  }
}

// ------------------------------------------------------------------------------------
// welding
// ------------------------------------------------------------------------------------

namespace {

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellKeyHash {
  std::size_t operator()(const CellKey& k) const {
    std::uint64_t h = std::uint64_t(k.x) * 0x9E3779B97F4A7C15ull;
    h ^= std::uint64_t(k.y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
    h ^= std::uint64_t(k.z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
    return std::size_t(h);
  }
};

}  // namespace

void weld_vertices(TriMesh& m, double tolerance) {
  const bool exact = !(tolerance > 0.0);
  const double inv = exact ? 0.0 : 1.0 / tolerance;
  auto cell_of = [&](const Vec3& p) {
    if (exact) {
      // Bit patterns (+0 and -0 normalised) so only identical positions merge.
      auto bits = [](double d) {
        d = d == 0.0 ? 0.0 : d;
        std::int64_t b;
        std::memcpy(&b, &d, sizeof b);
        return b;
      };
      return CellKey{bits(p.x()), bits(p.y()), bits(p.z())};
    }
    return CellKey{std::int64_t(std::floor(p.x() * inv)), std::int64_t(std::floor(p.y() * inv)),
                   std::int64_t(std::floor(p.z() * inv))};
  };

  std::vector<Vec3> out;
  out.reserve(m.vertices.size());
  std::vector<std::uint32_t> remap(m.vertices.size(), kNoTriangle);
  std::unordered_map<CellKey, std::uint32_t, CellKeyHash> head;  // cell -> first new vertex
  std::vector<std::uint32_t> next;                                // chain within a cell
  head.reserve(m.vertices.size());
  next.reserve(m.vertices.size());
  const double tol2 = tolerance * tolerance;

  auto find_or_add = [&](std::uint32_t old) -> std::uint32_t {
    const Vec3& p = m.vertices[old];
    const CellKey c = cell_of(p);
    const int r = exact ? 0 : 1;
    for (int dx = -r; dx <= r; ++dx)
      for (int dy = -r; dy <= r; ++dy)
        for (int dz = -r; dz <= r; ++dz) {
          auto it = head.find({c.x + dx, c.y + dy, c.z + dz});
          if (it == head.end()) continue;
          for (std::uint32_t k = it->second; k != kNoTriangle; k = next[k]) {
            if (exact ? out[k] == p : (out[k] - p).squaredNorm() <= tol2) return k;
          }
        }
    const std::uint32_t k = std::uint32_t(out.size());
    out.push_back(p);
    auto [it, inserted] = head.try_emplace(c, k);
    next.push_back(inserted ? kNoTriangle : it->second);
    if (!inserted) it->second = k;
    return k;
  };

  for (auto& tri : m.triangles) {
    for (auto& v : tri) {
      if (remap[v] == kNoTriangle) remap[v] = find_or_add(v);
      v = remap[v];
    }
  }
  m.vertices = std::move(out);
}

// ------------------------------------------------------------------------------------
// validation and queries
// ------------------------------------------------------------------------------------

Aabb bounding_box(const TriMesh& m) {
  Aabb b;
  for (const auto& v : m.vertices) b.extend(v);
  return b;
}

namespace {

std::string fmt_vec(const Vec3& v) {
  std::ostringstream s;
  s.precision(9);
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

void check_finite_vertices(const TriMesh& m, const std::string& source) {
  for (std::size_t v = 0; v < m.vertices.size(); ++v) {
    if (!m.vertices[v].allFinite()) {
      throw InputError(source, "vertex " + std::to_string(v) + " has a non-finite coordinate " +
                                   fmt_vec(m.vertices[v]) +
                                   "; fix or re-export the mesh (NaN/inf are not allowed)");
    }
  }
}

}  // namespace

void validate_mesh(const TriMesh& m, const std::string& source) {
  if (m.triangles.empty()) {
    throw InputError(source, "mesh has zero triangles; a structure mesh needs at least one "
                             "triangle (check the file is not empty or truncated)");
  }
  check_finite_vertices(m, source);
  if (m.triangle_part.size() != m.triangles.size()) {
    throw InputError(source, "triangle_part has " + std::to_string(m.triangle_part.size()) +
                                 " entries for " + std::to_string(m.triangles.size()) +
                                 " triangles; give every triangle a part");
  }
  const std::size_t nv = m.vertices.size();
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const auto& tri = m.triangles[t];
    for (auto v : tri) {
      if (v >= nv) {
        throw InputError(source, "triangle " + std::to_string(t) + " uses vertex " +
                                     std::to_string(v) + " but the mesh has " +
                                     std::to_string(nv) + " vertices");
      }
    }
    if (m.triangle_part[t] >= m.part_names.size()) {
      throw InputError(source, "triangle " + std::to_string(t) + " has part " +
                                   std::to_string(m.triangle_part[t]) + " but only " +
                                   std::to_string(m.part_names.size()) + " parts are named");
    }
    const Vec3& a = m.vertices[tri[0]];
    const Vec3& b = m.vertices[tri[1]];
    const Vec3& c = m.vertices[tri[2]];
    const double lmax2 =
        std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    const double area2 = (b - a).cross(c - a).norm();  // twice the area
    // Zero (or sliver: height < 1e-12 of the longest side) area: no usable normal.
    if (!(area2 > 1e-12 * lmax2)) {
      throw InputError(source, "triangle " + std::to_string(t) +
                                   " is degenerate (zero area) with corners " + fmt_vec(a) +
                                   ", " + fmt_vec(b) + ", " + fmt_vec(c) +
                                   " (after merging vertices closer than the weld tolerance); "
                                   "remove it or re-export the mesh");
    }
  }
}

bool is_closed(const TriMesh& mesh) {
  if (mesh.triangles.empty()) return false;
  if (!mesh.has_topology()) {
    TriMesh copy = mesh;
    build_topology(copy);
    return is_closed(copy);
  }
  return std::all_of(mesh.edge_triangle_count.begin(), mesh.edge_triangle_count.end(),
                     [](std::uint32_t c) { return c == 2; });
}

bool is_consistently_oriented(const TriMesh& mesh) {
  if (!mesh.has_topology()) {
    TriMesh copy = mesh;
    build_topology(copy);
    return is_consistently_oriented(copy);
  }
  // Direction in which triangle t walks edge e: +1 from edges[e][0] to edges[e][1].
  auto direction = [&](std::uint32_t t, std::uint32_t e) {
    for (int i = 0; i < 3; ++i) {
      if (mesh.triangle_edges[t][i] == e) return mesh.triangles[t][i] == mesh.edges[e][0] ? 1 : -1;
    }
    return 0;
  };
  for (std::uint32_t e = 0; e < mesh.edges.size(); ++e) {
    const auto n = mesh.edge_triangle_count[e];
    if (n > 2) return false;
    if (n == 2) {
      const auto& et = mesh.edge_triangles[e];
      if (et[1] == kNoTriangle) return false;  // the same triangle twice
      if (direction(et[0], e) + direction(et[1], e) != 0) return false;
    }
  }
  return true;
}

double signed_volume(const TriMesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) {
    v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]]));
  }
  return v / 6.0;
}

Vec3 triangle_normal(const TriMesh& m, std::uint32_t t) {
  const auto& tri = m.triangles[t];
  const Vec3& a = m.vertices[tri[0]];
  return (m.vertices[tri[1]] - a).cross(m.vertices[tri[2]] - a).normalized();
}

// ------------------------------------------------------------------------------------
// file I/O
// ------------------------------------------------------------------------------------

namespace {

std::string read_whole_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw InputError(path, "mesh file not found; check the path (relative paths are resolved "
                           "against the current working directory)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open mesh file for reading; check its permissions");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string file_stem(const std::string& path) {
  std::string s = std::filesystem::path(path).stem().string();
  return s.empty() ? "mesh" : s;
}

std::string_view trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r\f\v");
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\f\v");
  return s.substr(b, e - b + 1);
}

/// Splits off the first whitespace-delimited token of `s`.
std::string_view next_token(std::string_view& s) {
  const auto b = s.find_first_not_of(" \t\r\f\v");
  if (b == std::string_view::npos) {
    s = {};
    return {};
  }
  s.remove_prefix(b);
  const auto e = s.find_first_of(" \t\r\f\v");
  std::string_view tok = s.substr(0, e);
  s.remove_prefix(e == std::string_view::npos ? s.size() : e);
  return tok;
}

bool parse_double(std::string_view tok, double& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}

/// Calls f(line_number (1-based), line) for every line.
template <class F>
void for_each_line(const std::string& text, F&& f) {
  std::size_t pos = 0;
  std::size_t line = 0;
  while (pos <= text.size()) {
    const auto nl = text.find('\n', pos);
    const std::size_t end = nl == std::string::npos ? text.size() : nl;
    ++line;
    f(line, std::string_view(text).substr(pos, end - pos));
    if (nl == std::string::npos) break;
    pos = nl + 1;
  }
}

std::string at_line(std::size_t line) { return "line " + std::to_string(line) + ": "; }

/// Reads three coordinates from `rest`; throws naming the line on failure.
Vec3 read_xyz(std::string_view rest, const std::string& path, std::size_t line,
              std::string_view what) {
  Vec3 p;
  for (int k = 0; k < 3; ++k) {
    const std::string_view tok = next_token(rest);
    if (tok.empty()) {
      throw InputError(path, at_line(line) + std::string(what) +
                                 " needs three coordinates x y z; add the missing numbers");
    }
    if (!parse_double(tok, p[k])) {
      throw InputError(path, at_line(line) + "bad number '" + std::string(tok) + "' in " +
                                 std::string(what) + "; coordinates must be decimal numbers");
    }
    if (!std::isfinite(p[k])) {
      throw InputError(path, at_line(line) + "non-finite coordinate '" + std::string(tok) +
                                 "' in " + std::string(what) +
                                 "; NaN/inf are not allowed, fix or re-export the mesh");
    }
  }
  return p;
}

void finish(TriMesh& m, const std::string& path, const MeshLoadOptions& opt) {
  if (m.triangles.empty()) {
    throw InputError(path, "mesh has zero triangles; check the file is a complete mesh "
                           "(not empty, not truncated)");
  }
  check_finite_vertices(m, path);
  // Finite coordinates can still span more than a double holds (1e308 and -1e308): the weld
  // tolerance would be inf and merge every vertex into one.
  const Aabb box = bounding_box(m);
  if (!std::isfinite(box.extent().norm()))
    throw InputError(path, "the mesh spans from " + fmt_vec(box.lo) + " to " + fmt_vec(box.hi) +
                               ", too large to measure; mesh coordinates are in metres: check the units or "
                               "re-export the mesh");
  double tol = opt.weld_tolerance;
  if (tol < 0.0) tol = 1e-6 * bounding_box(m).extent().norm();
  weld_vertices(m, tol);
  validate_mesh(m, path);
  build_topology(m);
}

TriMesh parse_stl_binary(const std::string& data, const std::string& path) {
  std::uint32_t n = 0;
  std::memcpy(&n, data.data() + 80, 4);
  TriMesh m;
  m.part_names = {file_stem(path)};
  m.vertices.reserve(3 * std::size_t(n));
  m.triangles.reserve(n);
  m.triangle_part.assign(n, 0);
  for (std::uint32_t t = 0; t < n; ++t) {
    const char* rec = data.data() + 84 + 50 * std::size_t(t);
    float f[9];
    std::memcpy(f, rec + 12, sizeof f);  // skip the stored normal: winding defines it
    for (int k = 0; k < 3; ++k) {
      const Vec3 p(f[3 * k], f[3 * k + 1], f[3 * k + 2]);
      if (!p.allFinite()) {
        throw InputError(path, "triangle " + std::to_string(t) + " corner " + std::to_string(k) +
                                   " has a non-finite coordinate " + fmt_vec(p) +
                                   "; NaN/inf are not allowed, fix or re-export the mesh");
      }
      m.vertices.push_back(p);
    }
    m.triangles.push_back({3 * t, 3 * t + 1, 3 * t + 2});
  }
  return m;
}

TriMesh parse_stl_ascii(const std::string& text, const std::string& path) {
  TriMesh m;
  std::size_t facet_line = 0;
  int facet_vertices = -1;  // -1: outside a facet
  std::vector<Vec3> pending;
  auto part_of = [&](std::string name) {
    if (name.empty()) name = file_stem(path);
    auto it = std::find(m.part_names.begin(), m.part_names.end(), name);
    if (it != m.part_names.end()) return std::uint16_t(it - m.part_names.begin());
    if (m.part_names.size() >= 0xFFFF) throw InputError(path, "more than 65535 solids (parts)");
    m.part_names.push_back(std::move(name));
    return std::uint16_t(m.part_names.size() - 1);
  };
  std::uint16_t part = 0;
  bool have_part = false;

  for_each_line(text, [&](std::size_t line, std::string_view s) {
    std::string_view rest = s;
    const std::string_view kw = next_token(rest);
    if (kw.empty()) return;
    if (kw == "solid") {
      part = part_of(std::string(trim(rest)));
      have_part = true;
    } else if (kw == "facet") {
      if (facet_vertices >= 0) {
        throw InputError(path, at_line(line) + "'facet' before the previous facet (line " +
                                   std::to_string(facet_line) + ") ended; add 'endfacet'");
      }
      facet_vertices = 0;
      facet_line = line;
    } else if (kw == "vertex") {
      if (facet_vertices < 0) {
        throw InputError(path, at_line(line) + "'vertex' outside a facet; wrap it in "
                                               "'facet normal ... outer loop ... endloop endfacet'");
      }
      pending.push_back(read_xyz(rest, path, line, "vertex"));
      ++facet_vertices;
    } else if (kw == "endfacet") {
      if (facet_vertices != 3) {
        throw InputError(path, at_line(facet_line) + "facet has " +
                                   std::to_string(std::max(facet_vertices, 0)) +
                                   " vertices; STL facets must be triangles (3 vertices)");
      }
      if (!have_part) {
        part = part_of("");
        have_part = true;
      }
      const std::uint32_t base = std::uint32_t(m.vertices.size());
      for (const auto& p : pending) m.vertices.push_back(p);
      pending.clear();
      m.triangles.push_back({base, base + 1, base + 2});
      m.triangle_part.push_back(part);
      facet_vertices = -1;
    } else if (kw == "outer" || kw == "endloop" || kw == "endsolid") {
      // structure only
    } else {
      throw InputError(path, at_line(line) + "unexpected '" + std::string(kw) +
                                 "' in ASCII STL; expected solid/facet/outer loop/vertex/"
                                 "endloop/endfacet/endsolid");
    }
  });
  if (facet_vertices >= 0) {
    throw InputError(path, at_line(facet_line) + "facet is not closed by 'endfacet' "
                                                 "(file truncated?)");
  }
  return m;
}

}  // namespace

TriMesh load_stl(const std::string& path, const MeshLoadOptions& options) {
  const std::string data = read_whole_file(path);
  const std::size_t size = data.size();
  std::uint32_t n = 0;
  if (size >= 84) std::memcpy(&n, data.data() + 80, 4);
  const bool binary_size_matches = size >= 84 && size == 84 + 50 * std::size_t(n);

  TriMesh m;
  if (binary_size_matches) {
    m = parse_stl_binary(data, path);
  } else {
    const std::string_view head = trim(std::string_view(data).substr(0, 512));
    // Binary headers often start with "solid" too, but binary data practically always
    // contains NUL bytes (zero attribute counts); ASCII never does.
    const bool ascii = head.substr(0, 5) == "solid" && data.find('\0') == std::string::npos;
    if (ascii) {
      m = parse_stl_ascii(data, path);
    } else if (size < 84) {
      throw InputError(path, "file has " + std::to_string(size) +
                                 " bytes: too short for a binary STL (84-byte header) and not "
                                 "ASCII STL (does not start with 'solid'); re-export the mesh");
    } else {
      throw InputError(path, "binary STL header says " + std::to_string(n) + " triangles (" +
                                 std::to_string(84 + 50 * std::size_t(n)) +
                                 " bytes) but the file has " + std::to_string(size) +
                                 " bytes; the file is truncated or corrupt, re-export it");
    }
  }
  finish(m, path, options);
  return m;
}

TriMesh load_obj(const std::string& path, const MeshLoadOptions& options) {
  const std::string text = read_whole_file(path);
  TriMesh m;
  std::string pending_name = file_stem(path);
  bool part_resolved = false;
  std::uint16_t part = 0;
  std::vector<std::uint32_t> poly;

  for_each_line(text, [&](std::size_t line, std::string_view s) {
    std::string_view rest = s;
    const std::string_view kw = next_token(rest);
    if (kw.empty() || kw.front() == '#') return;
    if (kw == "v") {
      m.vertices.push_back(read_xyz(rest, path, line, "vertex 'v'"));
    } else if (kw == "g" || kw == "o") {
      std::string_view name = trim(rest);
      if (const auto h = name.find('#'); h != std::string_view::npos) name = trim(name.substr(0, h));
      pending_name = name.empty() ? std::string("default") : std::string(name);
      part_resolved = false;
    } else if (kw == "f") {
      poly.clear();
      const std::size_t nv = m.vertices.size();
      for (std::string_view tok = next_token(rest); !tok.empty(); tok = next_token(rest)) {
        if (tok.front() == '#') break;
        const std::string_view idx = tok.substr(0, tok.find('/'));
        long long i = 0;
        const auto r = std::from_chars(idx.data(), idx.data() + idx.size(), i);
        if (r.ec != std::errc() || r.ptr != idx.data() + idx.size()) {
          throw InputError(path, at_line(line) + "bad vertex index '" + std::string(tok) +
                                     "' in face; use v, v/vt, v//vn or v/vt/vn with integer v");
        }
        const long long k = i > 0 ? i - 1 : static_cast<long long>(nv) + i;
        if (i == 0 || k < 0 || k >= static_cast<long long>(nv)) {
          throw InputError(path, at_line(line) + "face vertex index " + std::to_string(i) +
                                     " is out of range: " + std::to_string(nv) +
                                     " vertices are defined before this line (indices are "
                                     "1-based, negative ones count back from the last vertex)");
        }
        poly.push_back(std::uint32_t(k));
      }
      if (poly.size() < 3) {
        throw InputError(path, at_line(line) + "face has " + std::to_string(poly.size()) +
                                   " vertices; a face needs at least 3");
      }
      if (!part_resolved) {
        auto it = std::find(m.part_names.begin(), m.part_names.end(), pending_name);
        if (it == m.part_names.end()) {
          if (m.part_names.size() >= 0xFFFF) {
            throw InputError(path, at_line(line) + "more than 65535 groups (parts)");
          }
          m.part_names.push_back(pending_name);
          it = m.part_names.end() - 1;
        }
        part = std::uint16_t(it - m.part_names.begin());
        part_resolved = true;
      }
      for (std::size_t j = 1; j + 1 < poly.size(); ++j) {
        m.triangles.push_back({poly[0], poly[j], poly[j + 1]});
        m.triangle_part.push_back(part);
      }
    }
    // vt, vn, s, usemtl, mtllib, l, ...: not needed for contact geometry.
  });
  finish(m, path, options);
  return m;
}

TriMesh load_mesh(const std::string& path, const MeshLoadOptions& options) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".stl") return load_stl(path, options);
  if (ext == ".obj") return load_obj(path, options);
  throw InputError(path, "unknown mesh format '" + ext + "'; use a .stl (ASCII or binary) or "
                                                         ".obj file");
}

void write_stl_binary(const TriMesh& m, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path, "cannot open for writing; check the directory exists");
  char header[80];
  std::memset(header, ' ', sizeof header);
  const char tag[] = "hybridsim binary STL (metres, z up)";
  std::memcpy(header, tag, sizeof tag - 1);
  out.write(header, sizeof header);
  const std::uint32_t n = std::uint32_t(m.triangles.size());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (std::uint32_t t = 0; t < n; ++t) {
    const Vec3 nrm = triangle_normal(m, t);
    float rec[12];
    for (int k = 0; k < 3; ++k) rec[k] = float(nrm[k]);
    for (int c = 0; c < 3; ++c) {
      const Vec3& p = m.vertices[m.triangles[t][c]];
      for (int k = 0; k < 3; ++k) rec[3 + 3 * c + k] = float(p[k]);
    }
    const std::uint16_t attr = 0;
    out.write(reinterpret_cast<const char*>(rec), sizeof rec);
    out.write(reinterpret_cast<const char*>(&attr), 2);
  }
  if (!out) throw InputError(path, "write failed (disk full?)");
}

void write_stl_ascii(const TriMesh& m, const std::string& path) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) throw InputError(path, "cannot open for writing; check the directory exists");
  out.precision(17);
  const std::size_t nparts = std::max<std::size_t>(m.part_names.size(), 1);
  for (std::size_t p = 0; p < nparts; ++p) {
    std::string name = p < m.part_names.size() ? m.part_names[p] : "";
    if (name.empty()) name = "part" + std::to_string(p);
    bool any = false;
    for (std::uint32_t t = 0; t < m.triangles.size(); ++t) {
      const std::size_t tp = t < m.triangle_part.size() ? m.triangle_part[t] : 0;
      if (tp != p) continue;
      if (!any) out << "solid " << name << "\n";
      any = true;
      const Vec3 nrm = triangle_normal(m, t);
      out << "  facet normal " << nrm.x() << " " << nrm.y() << " " << nrm.z() << "\n"
          << "    outer loop\n";
      for (int c = 0; c < 3; ++c) {
        const Vec3& v = m.vertices[m.triangles[t][c]];
        out << "      vertex " << v.x() << " " << v.y() << " " << v.z() << "\n";
      }
      out << "    endloop\n  endfacet\n";
    }
    if (any) out << "endsolid " << name << "\n";
  }
  if (!out) throw InputError(path, "write failed (disk full?)");
}

}  // namespace hs::mesh

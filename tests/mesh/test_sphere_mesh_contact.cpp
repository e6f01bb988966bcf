// Sphere - mesh contact: analytic plane/line/point contacts, no double counting across
// shared edges and vertices, the grid, moving meshes, STL vs parametric pier.
#include "mesh_fixtures.h"

#include "bonded/contact_linear.h"
#include "common/ice_formulas.h"
#include "mesh/pier.h"
#include "mesh/sphere_mesh_contact.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>

// ---- allocation counter for the "query does not allocate" test ----
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<long> g_allocations{0};
}
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace hs::mesh {
namespace {

// Ice particle in paper units; kn from the paper's Eq. 1.
constexpr double kE = 1e9;
constexpr double kR = 0.1;
constexpr double kDelta = 0.01;
double kn_for(double radius) { return eq1_contact_stiffness(kE, 2.0 * radius); }

/// Total force on the sphere from all contacts, via the linear contact law
/// (static contact: no relative velocity, no tangential history).
Vec3 total_force(const std::vector<MeshContact>& contacts, double radius) {
  bonded::LinearContactParams p;
  p.kn = p.kt = kn_for(radius);
  p.mu = 0.3;
  Vec3 f = Vec3::Zero();
  for (const auto& k : contacts) {
    Vec3 xi = Vec3::Zero();
    f += bonded::linear_contact(p, k.overlap, k.normal, 0.0, Vec3::Zero(), 1.0, 1e-5, xi).force;
  }
  return f;
}

// Callers use rel = 1.5e-13: measured at most 1.3e-14 relative over all of them (was 1e-12).
void expect_force_equal(const Vec3& got, const Vec3& want, double rel) {
  EXPECT_LE((got - want).norm(), rel * want.norm()) << "got " << got.transpose() << " want "
                                                    << want.transpose();
}

/// Independent closest point on a triangle (Ericson, Real-Time Collision Detection 5.1.5).
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  }
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double brute_distance(const TriMesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : m.triangles) {
    const Vec3 q = closest_on_triangle(p, m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]);
    best = std::min(best, (p - q).norm());
  }
  return best;
}

struct Query {
  std::vector<MeshContact> out;
  MeshQueryScratch scratch;
  const std::vector<MeshContact>& operator()(const MeshGrid& g, const Vec3& c, double r) {
    g.query(c, r, out, scratch);
    return out;
  }
};

// ---------------------------------------------------------------------------------
// Face, edge, vertex: exact analytic plane, line and point
// ---------------------------------------------------------------------------------

TEST(SphereMeshContact, FaceIsTheAnalyticPlane) {
  const MeshGrid grid(test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1)), kR);
  Query q;
  const Vec3 c(0.3, 0.62, 1.0 + kR - kDelta);
  const auto& k = q(grid, c, kR);
  ASSERT_EQ(k.size(), 1u);
  EXPECT_EQ(k[0].feature, MeshContact::Face);
  EXPECT_EQ(k[0].normal, Vec3(0, 0, 1));
  EXPECT_NEAR(k[0].overlap, kDelta, 1e-15);
  EXPECT_NEAR((k[0].point - Vec3(0.3, 0.62, 1.0)).norm(), 0.0, 1e-15);
  expect_force_equal(total_force(k, kR), kn_for(kR) * kDelta * Vec3(0, 0, 1), 1.5e-13);

  // Exactly above the top face's diagonal (shared by two coplanar triangles): one
  // contact, still the plane.
  const auto& d = q(grid, Vec3(0.4, 0.4, 1.0 + kR - kDelta), kR);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].feature, MeshContact::Edge);
  EXPECT_NEAR((d[0].normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(d[0].overlap, kDelta, 1e-15);
  expect_force_equal(total_force(d, kR), kn_for(kR) * kDelta * Vec3(0, 0, 1), 1.5e-13);
}

TEST(SphereMeshContact, ConvexEdgeIsTheAnalyticLine) {
  const MeshGrid grid(test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1)), kR);
  Query q;
  // Edge x = 1, z = 1 (between the top face and the +x face).
  for (double deg : {0.5, 10.0, 45.0, 77.0, 89.5}) {
    const double th = deg * kPi / 180.0;
    const Vec3 n(std::cos(th), 0.0, std::sin(th));
    const Vec3 on_edge(1.0, 0.37, 1.0);
    const auto& k = q(grid, on_edge + (kR - kDelta) * n, kR);
    ASSERT_EQ(k.size(), 1u) << deg;
    EXPECT_EQ(k[0].feature, MeshContact::Edge);
    EXPECT_NEAR((k[0].normal - n).norm(), 0.0, 1e-14);
    EXPECT_NEAR(k[0].overlap, kDelta, 1e-15);
    EXPECT_NEAR((k[0].point - on_edge).norm(), 0.0, 1e-15);
    expect_force_equal(total_force(k, kR), kn_for(kR) * kDelta * n, 1.5e-13);
  }
}

TEST(SphereMeshContact, CornerIsTheAnalyticPoint) {
  const MeshGrid grid(test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1)), kR);
  Query q;
  for (const Vec3& dir : {Vec3(1, 1, 1), Vec3(1, 2, 3), Vec3(0.05, 1, 0.1)}) {
    const Vec3 n = dir.normalized();
    const auto& k = q(grid, Vec3(1, 1, 1) + (kR - kDelta) * n, kR);
    ASSERT_EQ(k.size(), 1u) << dir.transpose();
    EXPECT_EQ(k[0].feature, MeshContact::Vertex);
    EXPECT_EQ(grid.mesh().vertices[k[0].feature_id], Vec3(1, 1, 1));
    EXPECT_NEAR((k[0].normal - n).norm(), 0.0, 1e-14);
    EXPECT_NEAR(k[0].overlap, kDelta, 1e-15);
    expect_force_equal(total_force(k, kR), kn_for(kR) * kDelta * n, 1.5e-13);
  }
}

// ---------------------------------------------------------------------------------
// No double counting
// ---------------------------------------------------------------------------------

TEST(SphereMeshContact, SharedEdgeOfCoplanarTrianglesGivesOneContact) {
  const MeshGrid grid(test::make_square(), kR);  // diagonal (0,0)-(1,1) is shared
  Query q;
  for (double s : {0.1, 0.5, 0.77}) {
    const auto& k = q(grid, Vec3(s, s, kR - kDelta), kR);
    ASSERT_EQ(k.size(), 1u) << s;
    EXPECT_EQ(k[0].feature, MeshContact::Edge);
    EXPECT_NEAR(k[0].overlap, kDelta, 5e-17);  // measured 5.2e-18 m (was 1e-15)
    expect_force_equal(total_force(k, kR), kn_for(kR) * kDelta * Vec3(0, 0, 1), 1.5e-13);
  }
}

TEST(SphereMeshContact, SharedVertexOfCoplanarFanGivesOneContact) {
  for (int n : {3, 6, 8, 17}) {
    const MeshGrid grid(test::make_fan(n, 1.0), kR);
    Query q;
    const auto& k = q(grid, Vec3(0, 0, kR - kDelta), kR);
    ASSERT_EQ(k.size(), 1u) << n;
    EXPECT_EQ(k[0].feature, MeshContact::Vertex);
    EXPECT_EQ(k[0].feature_id, 0u);
    expect_force_equal(total_force(k, kR), kn_for(kR) * kDelta * Vec3(0, 0, 1), 1.5e-13);
  }
}

TEST(SphereMeshContact, NearSharedFeatureOverOneFaceGivesOnlyTheFace) {
  Query q;
  {
    const MeshGrid grid(test::make_square(), kR);
    const auto& k = q(grid, Vec3(0.5 + 1e-3, 0.5 - 1e-3, kR - kDelta), kR);
    ASSERT_EQ(k.size(), 1u);
    EXPECT_EQ(k[0].feature, MeshContact::Face);
    EXPECT_EQ(k[0].triangle, 0u);
    EXPECT_NEAR(k[0].overlap, kDelta, 5e-17);  // measured 5.2e-18 m (was 1e-15)
  }
  {
    // Over triangle 0 of an 8-fan (0..45 deg), near the centre vertex: the edges of the
    // non-adjacent triangles (at 90 deg, ...) are within r too but are not the closest
    // point of the surface; only the face may count.
    const MeshGrid grid(test::make_fan(8, 1.0), kR);
    const double a = 40.0 * kPi / 180.0;
    for (double rho : {1e-6, 1e-3, 0.02}) {
      const auto& k = q(grid, Vec3(rho * std::cos(a), rho * std::sin(a), kR - kDelta), kR);
      ASSERT_EQ(k.size(), 1u) << rho;
      EXPECT_EQ(k[0].feature, MeshContact::Face);
      EXPECT_EQ(k[0].triangle, 0u);
      expect_force_equal(total_force(k, kR), kn_for(kR) * kDelta * Vec3(0, 0, 1), 1.5e-13);
    }
  }
}

TEST(SphereMeshContact, RandomSpheresOnABoxTouchExactlyOnce) {
  // Convex closed mesh: every sphere within r of the box gets exactly one contact, with
  // the overlap and normal of the true closest point.
  const Vec3 lo(0, 0, 0), hi(1, 0.7, 0.4);
  const MeshGrid grid(test::make_box(lo, hi), kR);
  Query q;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-kR, 1.0 + kR);
  int tested = 0;
  while (tested < 20000) {
    const Vec3 c(u(rng), u(rng) * 0.7, u(rng) * 0.4);
    const Vec3 closest = c.cwiseMax(lo).cwiseMin(hi);
    const double dist = (c - closest).norm();
    if (dist == 0.0 || dist >= kR) continue;
    ++tested;
    const auto& k = q(grid, c, kR);
    ASSERT_EQ(k.size(), 1u) << c.transpose();
    EXPECT_NEAR(k[0].overlap, kR - dist, 1e-14);
    EXPECT_NEAR((k[0].normal - (c - closest) / dist).norm(), 0.0, 3e-13);  // measured 2.9e-14 (was 1e-9)
  }
}

TEST(SphereMeshContact, RandomSpheresOnAFlatFanTouchExactlyOnce) {
  // Open mesh (two-sided): a plane made of 11 thin triangles around one vertex.
  const MeshGrid grid(test::make_fan(11, 1.0), kR);
  EXPECT_TRUE(grid.two_sided());
  Query q;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::uniform_real_distribution<double> h(-kR, kR);
  for (int i = 0; i < 20000; ++i) {
    const Vec3 c(0.6 * u(rng), 0.6 * u(rng), h(rng));
    if (c.z() == 0.0) continue;
    const auto& k = q(grid, c, kR);
    ASSERT_EQ(k.size(), 1u) << c.transpose();
    EXPECT_NEAR(k[0].overlap, kR - std::abs(c.z()), 1e-14);
    EXPECT_NEAR((k[0].normal - Vec3(0, 0, c.z() > 0 ? 1 : -1)).norm(), 0.0, 1e-9);
  }
}

TEST(SphereMeshContact, RandomSpheresOnTheConeMatchBruteForceClosestPoint) {
  // The polygonal cone between the neck and the annulus is convex (seams and the
  // cone/annulus rim are convex edges): one contact, at the brute-force distance.
  const PierParams p;
  const TriMesh pier = make_pier(p);
  const double r = 0.3;
  const MeshGrid grid(pier, r);
  Query q;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> phi(0.0, 2.0 * kPi);
  std::uniform_real_distribution<double> zs(p.cone_bottom_z, 1.4);
  std::uniform_real_distribution<double> out(0.0, r);
  std::uniform_real_distribution<double> scale(0.9, 1.05);
  const double sa = std::sin(52.0 * kPi / 180.0), ca = std::cos(52.0 * kPi / 180.0);
  const double r_base = pier_cone_radius(p, p.cone_bottom_z);
  int tested = 0;
  for (int i = 0; i < 30000; ++i) {
    const double f = phi(rng);
    Vec3 c;
    if (i % 3 != 2) {
      // Outside the circular cone (so outside the inscribed polygonal one).
      const double z = zs(rng);
      const double rad = pier_cone_radius(p, z);
      const Vec3 n(sa * std::cos(f), sa * std::sin(f), ca);
      c = Vec3(rad * std::cos(f), rad * std::sin(f), z) + out(rng) * n;
    } else {
      // Below the annulus near the rim, or beside the rim.
      const double s = scale(rng) * r_base;
      c = Vec3(s * std::cos(f), s * std::sin(f), p.cone_bottom_z - out(rng));
    }
    const double dist = brute_distance(pier, c);
    if (dist >= r || dist < 1e-6) continue;
    ++tested;
    const auto& k = q(grid, c, r);
    ASSERT_EQ(k.size(), 1u) << c.transpose();
    EXPECT_NEAR(k[0].overlap, r - dist, 4e-14);  // measured 3.9e-15 m (was 1e-12)
    EXPECT_EQ(pier.part_names[k[0].part], "cone");
  }
  EXPECT_GT(tested, 5000);
}

TEST(SphereMeshContact, TheColumnRisesToTheDeckWithNoCapBelowIt) {
  // A pile particle above z = +6 m (where a 4 m neck would end in a flat cap) meets the column's
  // side, which pushes it horizontally and holds nothing up; the only upward face is the deck
  // cap at z = +20 m. With a 4 m neck the sphere against the column at z = 7 m finds no contact,
  // and one resting at z = 6 m on the column's top finds an upward normal (the cap).
  const PierParams p;  // defaults: deck at z = kPierDefaultDeckZ
  ASSERT_DOUBLE_EQ(p.cone_top_z + p.neck_height, kPierDefaultDeckZ);
  const TriMesh pier = make_pier(p);
  double z_max = -1e9;
  for (const auto& v : pier.vertices) z_max = std::max(z_max, v.z());
  EXPECT_EQ(z_max, kPierDefaultDeckZ);
  EXPECT_EQ(pier.triangles.size(), 10u * 64u);  // as many triangles as a short neck: contact cost unchanged
  const MeshGrid grid(pier, 0.5);
  Query q;
  const double half = kPi / 64.0;  // middle of segment 0
  const Vec3 radial(std::cos(half), std::sin(half), 0.0);
  const double apothem = pier_cone_radius(p, p.cone_top_z) * std::cos(half), r = 0.1, d = 0.01;
  for (const double z : {6.05, 7.0, 8.5, 12.0, 19.5}) {
    const auto& k = q(grid, (apothem + r - d) * radial + Vec3(0, 0, z), r);
    ASSERT_EQ(k.size(), 1u) << "z = " << z;
    EXPECT_EQ(pier.part_names[k[0].part], "neck");
    EXPECT_NEAR(k[0].overlap, d, 1e-12);
    EXPECT_LT(std::abs(k[0].normal.z()), 1e-12) << "z = " << z;  // measured 0: a vertical face
  }
  // A sphere on the axis side of the column's edge at z = 6 m (the top of a 4 m neck): inside the
  // column's solid, more than r from any face, so no contact pushes it up.
  const auto& k = q(grid, (apothem - 0.5) * radial + Vec3(0, 0, 6.0 + r - d), r);
  for (const auto& c : k) EXPECT_LT(c.normal.z(), 0.5);
  // Upward normals only at the deck.
  const auto& top = q(grid, Vec3(0.5, 0.0, kPierDefaultDeckZ + r - d), r);
  ASSERT_EQ(top.size(), 1u);
  EXPECT_NEAR(top[0].normal.z(), 1.0, 1e-12);
}

TEST(SphereMeshContact, ConcaveCornerGivesOneContactPerWall) {
  // In the corner under the annulus, against the shaft: the shaft face and the annulus
  // face both push, each with its own plane overlap.
  const PierParams p;
  const MeshGrid grid(make_pier(p), 0.5);
  Query q;
  const double half = kPi / 64.0;  // middle of segment 0
  const double apothem = 0.5 * p.shaft_diameter * std::cos(half);
  const Vec3 radial(std::cos(half), std::sin(half), 0.0);
  const double r = 0.3, d_shaft = 0.02, d_annulus = 0.005;
  const Vec3 c = (apothem + r - d_shaft) * radial + Vec3(0, 0, p.cone_bottom_z - (r - d_annulus));
  const auto& k = q(grid, c, r);
  ASSERT_EQ(k.size(), 2u);
  for (const auto& x : k) EXPECT_EQ(x.feature, MeshContact::Face);
  const Vec3 want = kn_for(r) * (d_shaft * radial + d_annulus * Vec3(0, 0, -1));
  expect_force_equal(total_force(k, r), want, 1.5e-13);
}

TEST(SphereMeshContact, CentreSlightlyInsideIsPushedOut) {
  // Closed mesh: one-sided. A centre 1 mm inside, under the top face and under the
  // top face's diagonal, is pushed up with overlap r + 1 mm.
  const MeshGrid grid(test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1)), kR);
  EXPECT_FALSE(grid.two_sided());
  Query q;
  for (const Vec3& c : {Vec3(0.3, 0.6, 0.999), Vec3(0.5, 0.5, 0.999)}) {
    const auto& k = q(grid, c, kR);
    ASSERT_EQ(k.size(), 1u);
    EXPECT_NEAR((k[0].normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);
    EXPECT_NEAR(k[0].overlap, kR + 1e-3, 1e-12);
  }
}

// ---------------------------------------------------------------------------------
// Grid, moving meshes, allocation, STL vs parametric
// ---------------------------------------------------------------------------------

TEST(SphereMeshContact, GridCellSizeDoesNotChangeTheAnswer) {
  const TriMesh pier = make_pier({});
  const MeshGrid fine(pier, 0.05);    // queries span many cells (the ~4 M-cell cap: 0.225 m over the 40 m pier)
  const MeshGrid coarse(pier, 50.0);  // one cell
  EXPECT_LT(fine.cell_size(), 0.25);
  Query a, b;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> phi(0.0, 2.0 * kPi), z(-21.0, 21.0), dr(-0.6, 0.6);
  int touching = 0;
  for (int i = 0; i < 20000; ++i) {
    const double f = phi(rng), zz = z(rng);
    const double rad = std::max(pier_radius_at({}, zz), 0.0) + dr(rng);
    const Vec3 c(rad * std::cos(f), rad * std::sin(f), zz);
    const auto& ka = a(fine, c, 0.4);
    const auto& kb = b(coarse, c, 0.4);
    ASSERT_EQ(ka.size(), kb.size());
    touching += !ka.empty();
    auto key = [](const MeshContact& k) { return std::pair(int(k.feature), k.feature_id); };
    auto sa = a.out, sb = b.out;
    std::sort(sa.begin(), sa.end(), [&](auto& x, auto& y) { return key(x) < key(y); });
    std::sort(sb.begin(), sb.end(), [&](auto& x, auto& y) { return key(x) < key(y); });
    for (std::size_t j = 0; j < sa.size(); ++j) {
      EXPECT_EQ(key(sa[j]), key(sb[j]));
      EXPECT_NEAR(sa[j].overlap, sb[j].overlap, 4e-15);  // measured 3.3e-16 m (was 1e-13)
    }
  }
  EXPECT_GT(touching, 1000);
}

TEST(SphereMeshContact, TranslatedMeshEqualsQueryInLocalFrame) {
  const TriMesh pier = make_pier({});
  TriMesh moved = pier;
  const Vec3 offset(12.5, -3.25, 0.75);
  for (auto& v : moved.vertices) v += offset;
  const MeshGrid local(pier, 0.3), world(moved, 0.3);
  Query a, b;
  const Vec3 c_world = Vec3(7.0 + 0.2, 0.31, 0.1) + offset;
  const auto& kl = a(local, c_world - offset, 0.3);
  const auto& kw = b(world, c_world, 0.3);
  ASSERT_EQ(kl.size(), 1u);
  ASSERT_EQ(kw.size(), 1u);
  // Measured 1.8e-15 m, 1.3e-15, 3.7e-15 m (limits were 1e-12).
  EXPECT_NEAR(kl[0].overlap, kw[0].overlap, 2e-14);
  EXPECT_NEAR((kl[0].normal - kw[0].normal).norm(), 0.0, 2e-14);
  EXPECT_NEAR((kl[0].point + offset - kw[0].point).norm(), 0.0, 4e-14);
}

TEST(SphereMeshContact, QueryDoesNotAllocateAfterWarmUp) {
  const MeshGrid grid(make_pier({}), 0.3);
  Query q;
  std::vector<Vec3> centres;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> phi(0.0, 2.0 * kPi), z(-5.0, 3.0), dr(-0.3, 0.3);
  for (int i = 0; i < 5000; ++i) {
    const double f = phi(rng), zz = z(rng);
    const double rad = pier_radius_at({}, zz) + dr(rng);
    centres.emplace_back(rad * std::cos(f), rad * std::sin(f), zz);
  }
  q.out.reserve(64);
  q.scratch.candidates.reserve(256);
  q(grid, centres[0], 0.3);  // sizes the per-triangle visit stamps
  std::size_t n = 0;
  const long before = g_allocations.load();
  for (const auto& c : centres) n += q(grid, c, 0.3).size();
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_GT(n, 100u);
}

TEST(SphereMeshContact, StlPierAndParametricPierGiveTheSameForce) {
  const PierParams p;
  const TriMesh pier = make_pier(p);
  const std::string path = test::tmp_file("pier_for_contact.stl");
  write_stl_ascii(pier, path);  // 17 significant digits: exact doubles
  const TriMesh from_stl = load_mesh(path);
  ASSERT_TRUE(is_closed(from_stl));
  const double r = 0.25;
  const MeshGrid g_param(pier, r), g_stl(from_stl, r);
  Query a, b;

  // On a seam (convex edge of the polygonal cone) at z = 0.5: analytic line contact.
  const double f5 = 2.0 * kPi * 5.0 / 64.0;
  const double sa = std::sin(52.0 * kPi / 180.0), ca = std::cos(52.0 * kPi / 180.0);
  const Vec3 n(sa * std::cos(f5), sa * std::sin(f5), ca);
  const double rad = pier_cone_radius(p, 0.5);
  const Vec3 c = Vec3(rad * std::cos(f5), rad * std::sin(f5), 0.5) + (r - 0.01) * n;
  const Vec3 fp = total_force(a(g_param, c, r), r);
  const Vec3 fs = total_force(b(g_stl, c, r), r);
  ASSERT_EQ(a.out.size(), 1u);
  EXPECT_EQ(a.out[0].feature, MeshContact::Edge);
  expect_force_equal(fs, fp, 1e-9);
  expect_force_equal(fp, kn_for(r) * 0.01 * n, 1e-9);  // the seam line, analytically

  // Many particles around the pier, the concave junctions included.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> phi(0.0, 2.0 * kPi), z(-20.5, 6.5), dr(-0.1, 0.3);
  int touching = 0;
  for (int i = 0; i < 5000; ++i) {
    const double f = phi(rng), zz = z(rng);
    const double rr = pier_radius_at(p, zz) + dr(rng);
    const Vec3 x(rr * std::cos(f), rr * std::sin(f), zz);
    const Vec3 f1 = total_force(a(g_param, x, r), r);
    const Vec3 f2 = total_force(b(g_stl, x, r), r);
    ASSERT_EQ(a.out.size(), b.out.size());
    if (a.out.empty()) continue;
    ++touching;
    EXPECT_LE((f1 - f2).norm(), 1e-14 * f1.norm()) << x.transpose();  // measured 0 (was 1e-9)
  }
  EXPECT_GT(touching, 1000);
}

}  // namespace
}  // namespace hs::mesh

// Pieces of ice: connected components over bonds, their sizes and horizontal extents.
#include "analysis/pieces.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace hs;
using namespace hs::analysis;

namespace {

/// A row of n particles of radius r at x = x0 + i d, y = y, gids from g0; bonded
/// neighbour to neighbour when `bonded`.
void row(std::vector<PieceParticle>& p, std::vector<PieceBond>& b, GlobalId g0, int n, double x0, double y,
         double d, double r, bool bonded) {
  for (int i = 0; i < n; ++i) {
    p.push_back({g0 + i, x0 + i * d, y, r});
    if (bonded && i > 0) b.push_back({g0 + i - 1, g0 + i});
  }
}

}  // namespace

TEST(Pieces, ComponentsSizesAndExtents) {
  std::vector<PieceParticle> p;
  std::vector<PieceBond> b;
  row(p, b, 100, 5, 0.0, 0.0, 0.5, 0.25, true);   // one piece of 5 along x: extent 4 * 0.5 + 2 * 0.25 = 2.5
  row(p, b, 200, 3, 10.0, 0.0, 0.0, 0.25, true);  // 3 at one point: extent 0.5 (the spheres)
  row(p, b, 300, 1, 20.0, 0.0, 0.0, 0.1, false);  // a lone particle
  for (int i = 0; i < 7; ++i) p.push_back({GlobalId(400 + i), 30.0, 0.3 * i, 0.15});  // a column along y
  for (int i = 1; i < 7; ++i) b.push_back({GlobalId(400 + i - 1), GlobalId(400 + i)});
  b.push_back({100, 999});  // a bond to a particle that is not there: ignored
  const Pieces s = find_pieces(p, b);
  ASSERT_EQ(s.size, (std::vector<std::int64_t>{7, 5, 3, 1}));
  ASSERT_EQ(s.extent.size(), 4u);
  EXPECT_NEAR(s.extent[0], 6 * 0.3 + 0.3, 1e-12);
  EXPECT_NEAR(s.extent[1], 2.5, 1e-12);
  EXPECT_NEAR(s.extent[2], 0.5, 1e-12);
  EXPECT_NEAR(s.extent[3], 0.2, 1e-12);

  // The input order does not matter (particles are taken in global-id order).
  std::mt19937 rng(7);
  std::shuffle(p.begin(), p.end(), rng);
  std::shuffle(b.begin(), b.end(), rng);
  const Pieces t = find_pieces(p, b);
  EXPECT_EQ(t.size, s.size);
  EXPECT_EQ(t.extent, s.extent);

  // One bond joins the row of 5 and the group of 3 into one piece of 8.
  b.push_back({104, 200});
  const Pieces u = find_pieces(p, b);
  ASSERT_EQ(u.size, (std::vector<std::int64_t>{8, 7, 1}));
  EXPECT_NEAR(u.extent[0], 10.0 + 0.25 - (0.0 - 0.25), 1e-12);
}

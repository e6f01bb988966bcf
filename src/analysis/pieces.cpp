#include "analysis/pieces.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace hs::analysis {

Pieces find_pieces(std::vector<PieceParticle> recs, const std::vector<PieceBond>& bonds) {
  std::sort(recs.begin(), recs.end(), [](const PieceParticle& a, const PieceParticle& b) { return a.gid < b.gid; });
  std::unordered_map<GlobalId, std::uint32_t> index;
  index.reserve(recs.size() * 2);
  for (std::size_t i = 0; i < recs.size(); ++i) index.emplace(recs[i].gid, static_cast<std::uint32_t>(i));
  const std::size_t n = recs.size();
  std::vector<std::uint32_t> parent(n);  // union-find, the smaller index as the root
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
    const PieceParticle& q = recs[i];
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

}  // namespace hs::analysis

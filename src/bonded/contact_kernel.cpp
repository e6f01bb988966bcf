// Contact history by name (engine.h, "friction history by name").
#include "engine.h"

#include <algorithm>
#include <cmath>
#include <type_traits>

#if defined(__AVX512F__) && defined(__AVX512VL__)
#include <immintrin.h>
#define HS_PAIR_GATHER_AVX512 1
#endif

namespace hs::bonded {

std::vector<PairHistory> Engine::contact_history() const {
  // A pending set_contact_history (carried_history_) takes precedence over the list, as it does
  // in the next neighbour rebuild.
  std::vector<PairHistory> out;
  out.reserve(carried_history_.size() + pairs_.size() / 2);
  for (const auto& [k, xi] : carried_history_)
    if (xi.squaredNorm() > 0.0) out.push_back({k.a, k.b, xi});
  const std::size_t from_carried = out.size();
  for (const auto& p : pairs_) {
    if (p.xi.squaredNorm() == 0.0) continue;
    const GlobalId gi = ps_.gid[p.i], gj = ps_.gid[p.j];
    const GidPair k = GidPair::of(gi, gj);
    if (from_carried != 0 && carried_history_.count(k) != 0) continue;
    out.push_back({k.a, k.b, gi < gj ? p.xi : Vec3(-p.xi)});
  }
  std::sort(out.begin(), out.end(),
            [](const PairHistory& x, const PairHistory& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  return out;
}

void Engine::set_contact_history(const std::vector<PairHistory>& h) {
  for (auto& p : pairs_) p.xi.setZero();
  carried_history_.clear();
  for (const auto& e : h) {
    const GidPair k = GidPair::of(e.a, e.b);
    carried_history_[k] = e.a < e.b ? e.xi : Vec3(-e.xi);
  }
  need_rebuild_ = true;
  forces_valid_ = false;
}

}  // namespace hs::bonded

namespace hs::bonded {

void Engine::refresh_wall_candidates() {
  // Between neighbour rebuilds every particle stays within skin/2 of where it was at the
  // rebuild, so within `skin` of where it is at any refresh; a wall may move skin/2 along its
  // normal before its list is refreshed. A particle further than r + 1.5 skin from the wall now
  // cannot touch it before the next refresh.
  const std::size_t n = ps_.owned();
  const double sk = skin();
  const bool rebuilt = wall_cand_rebuild_ != stats_.neighbor_rebuilds || wall_cand_.size() != walls_.size();
  wall_cand_.resize(walls_.size());
  wall_at_cand_.resize(walls_.size());
  for (std::size_t k = 0; k < walls_.size(); ++k) {
    const PlaneWall& w = walls_[k];
    const PlaneWall& c = wall_at_cand_[k];
    if (!rebuilt && w.normal == c.normal && std::abs((w.point - c.point).dot(w.normal)) <= 0.5 * sk) continue;
    auto& list = wall_cand_[k];
    auto& hist = wall_hist_[k];
    list.clear();
    const double reach = 1.5 * sk;
    for (std::size_t i = 0; i < n; ++i) {
      if ((ps_.x[i] - w.point).dot(w.normal) < ps_.radius[i] + reach)
        list.push_back(static_cast<std::uint32_t>(i));
      else
        hist[i].setZero();  // (dist >= r: the full loop would have zeroed it now)
    }
    wall_at_cand_[k] = w;
  }
  wall_cand_rebuild_ = stats_.neighbor_rebuilds;
}

}  // namespace hs::bonded

// ---------------------------------------------------------------- the pair kernel
//
// The pair list is a half list in cell order (build_neighbors: owned particles sorted by cell,
// each particle's partners j > i contiguous), and each pair carries its tangential spring.
// The loop runs in blocks of kBlock pairs:
//   1. gather (eight pairs at a time with AVX-512, else scalar): the touching pairs of the block
//      into structure-of-arrays scratch; pairs apart have their spring cleared, as in pair_forces;
//   2. law (vectorised, no branches): forces, torques, new springs, overlap ratios;
//   3. scatter (scalar, in list order): forces and torques onto the particles, springs back.
// Each particle's force is summed in the list's order, so the result does not depend on the
// block size or vector width and is bit-identical from run to run. The plane walls' kernel
// (wall_kernel_impl, at the end) does the same per wall over its candidates.

namespace hs::bonded {

namespace {

constexpr int kBlock = 128;
constexpr int kLanes = 8;  // the widest vector (AVX-512 doubles); kBlock is a multiple of it
static_assert(kBlock % kLanes == 0);

// The gather's lists (dx .. rj, pair) are kLanes longer than a block: the AVX-512 gather stores
// eight lanes at a time at the list's end, of which only the touching ones count.
constexpr int kList = kBlock + kLanes;

struct Block {
  alignas(64) double dx[kList], dy[kList], dz[kList];
  alignas(64) double ri[kList], rj[kList], smeff[kBlock];
  alignas(64) double dvx[kBlock], dvy[kBlock], dvz[kBlock];
  alignas(64) double wix[kBlock], wiy[kBlock], wiz[kBlock], wjx[kBlock], wjy[kBlock], wjz[kBlock];
  alignas(64) double xix[kBlock], xiy[kBlock], xiz[kBlock];
  // out
  alignas(64) double fx[kBlock], fy[kBlock], fz[kBlock];
  alignas(64) double tix[kBlock], tiy[kBlock], tiz[kBlock], tjx[kBlock], tjy[kBlock], tjz[kBlock];
  alignas(64) double delta[kBlock];
  std::uint32_t pair[kList];
};

#ifdef HS_PAIR_GATHER_AVX512
// Eight particles' (x, y, z, r) rows, as read from the packed copy, into four vectors of eight
// lanes: x, y, z, r.
inline void transpose8x4(const __m256d a[8], __m512d& X, __m512d& Y, __m512d& Z, __m512d& R) {
  const __m512d t0 = _mm512_insertf64x4(_mm512_castpd256_pd512(a[0]), a[4], 1);
  const __m512d t1 = _mm512_insertf64x4(_mm512_castpd256_pd512(a[1]), a[5], 1);
  const __m512d t2 = _mm512_insertf64x4(_mm512_castpd256_pd512(a[2]), a[6], 1);
  const __m512d t3 = _mm512_insertf64x4(_mm512_castpd256_pd512(a[3]), a[7], 1);
  const __m512d u0 = _mm512_unpacklo_pd(t0, t1);  // x0 x1 z0 z1 | x4 x5 z4 z5
  const __m512d u1 = _mm512_unpackhi_pd(t0, t1);  // y0 y1 r0 r1 | y4 y5 r4 r5
  const __m512d u2 = _mm512_unpacklo_pd(t2, t3);  // x2 x3 z2 z3 | x6 x7 z6 z7
  const __m512d u3 = _mm512_unpackhi_pd(t2, t3);  // y2 y3 r2 r3 | y6 y7 r6 r7
  const __m512i lo = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
  const __m512i hi = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
  X = _mm512_permutex2var_pd(u0, lo, u2);
  Z = _mm512_permutex2var_pd(u0, hi, u2);
  Y = _mm512_permutex2var_pd(u1, lo, u3);
  R = _mm512_permutex2var_pd(u1, hi, u3);
}

// Three doubles (a Vec3) into the low lanes of a vector; the fourth lane is masked, so the load
// does not read past the three (no fault at an array's end).
inline __m256d load3(const double* p) { return _mm256_maskz_loadu_pd(0x7, p); }

// Eight rows (x, y, z, .) into three vectors of eight lanes, stored at X, Y, Z.
inline void store_columns(const __m256d rows[8], double* X, double* Y, double* Z) {
  __m512d x, y, z, unused;
  transpose8x4(rows, x, y, z, unused);
  _mm512_store_pd(X, x);
  _mm512_store_pd(Y, y);
  _mm512_store_pd(Z, z);
}
#endif

// contact_lane for a kernel lane: a lane with smeff = 0 (two immovable particles, or an idle
// lane) gets no force and keeps its spring.
template <class Law>
[[gnu::always_inline]] inline void lane_or_idle(const Law& law, double delta, double rstar, double smeff, double nx,
                                                double ny, double nz, double vn, double vtx, double vty, double vtz,
                                                double dt, double& xi_x, double& xi_y, double& xi_z, double& fx,
                                                double& fy, double& fz) {
  const bool act = smeff != 0.0;
  double xix = xi_x, xiy = xi_y, xiz = xi_z;
  contact_lane(law, delta, rstar, smeff, nx, ny, nz, vn, vtx, vty, vtz, dt, xix, xiy, xiz, fx, fy, fz);
  fx = act ? fx : 0.0;
  fy = act ? fy : 0.0;
  fz = act ? fz : 0.0;
  xi_x = act ? xix : xi_x;
  xi_y = act ? xiy : xi_y;
  xi_z = act ? xiz : xi_z;
}

// The law for the block's lanes (contact_lane.h); a lane with smeff = 0 (two immovable particles,
// or an idle lane) gets no force and keeps its spring.
template <class Law>
void block_law(Block& b, int m, const Law& law, double dt) {
#pragma omp simd
  for (int k = 0; k < m; ++k) {
    const double d2 = b.dx[k] * b.dx[k] + b.dy[k] * b.dy[k] + b.dz[k] * b.dz[k];
    const double dist = std::sqrt(d2);
    const double inv = 1.0 / dist;
    const double nx = b.dx[k] * inv, ny = b.dy[k] * inv, nz = b.dz[k] * inv;
    const double rs = b.ri[k] + b.rj[k];
    const double delta = rs - dist;
    const double si = b.ri[k] - 0.5 * delta, sj = b.rj[k] - 0.5 * delta;
    // contact arms ai = si n (from i), aj = -sj n (from j)
    const double aix = si * nx, aiy = si * ny, aiz = si * nz;
    const double ajx = -sj * nx, ajy = -sj * ny, ajz = -sj * nz;
    // vrel = v_j + w_j x aj - v_i - w_i x ai
    const double vx = b.dvx[k] + (b.wjy[k] * ajz - b.wjz[k] * ajy) - (b.wiy[k] * aiz - b.wiz[k] * aiy);
    const double vy = b.dvy[k] + (b.wjz[k] * ajx - b.wjx[k] * ajz) - (b.wiz[k] * aix - b.wix[k] * aiz);
    const double vz = b.dvz[k] + (b.wjx[k] * ajy - b.wjy[k] * ajx) - (b.wix[k] * aiy - b.wiy[k] * aix);
    const double vn = vx * nx + vy * ny + vz * nz;
    const double vtx = vx - vn * nx, vty = vy - vn * ny, vtz = vz - vn * nz;
    const double rstar = b.ri[k] * b.rj[k] / rs;
    double fx, fy, fz;
    lane_or_idle(law, delta, rstar, b.smeff[k], nx, ny, nz, vn, vtx, vty, vtz, dt, b.xix[k], b.xiy[k], b.xiz[k], fx, fy,
                 fz);
    b.fx[k] = fx;
    b.fy[k] = fy;
    b.fz[k] = fz;
    b.tix[k] = aiy * fz - aiz * fy;
    b.tiy[k] = aiz * fx - aix * fz;
    b.tiz[k] = aix * fy - aiy * fx;
    b.tjx[k] = ajy * fz - ajz * fy;
    b.tjy[k] = ajz * fx - ajx * fz;
    b.tjz[k] = ajx * fy - ajy * fx;
    b.delta[k] = b.smeff[k] != 0.0 ? delta : 0.0;
  }
}

// One block of a plane wall's touching candidates (wall_kernel_impl): inputs, then outputs.
struct WallBlock {
  alignas(64) double delta[kBlock], r[kBlock], m[kBlock];
  alignas(64) double vx[kBlock], vy[kBlock], vz[kBlock], wx[kBlock], wy[kBlock], wz[kBlock];
  alignas(64) double xix[kBlock], xiy[kBlock], xiz[kBlock];
  alignas(64) double fx[kBlock], fy[kBlock], fz[kBlock], tx[kBlock], ty[kBlock], tz[kBlock];
  std::uint32_t particle[kBlock];
};

// The law between a plane wall (unit normal n towards the particles, velocity u) and the block's
// particles: a wall is a sphere of infinite radius and mass, so R* = r and m_eff = m; the arm
// from a particle's centre to the contact point is a = -(r - delta/2) n. A lane with m = 0 is
// idle (no force).
template <class Law>
void wall_block_law(WallBlock& b, int m, const Law& law, const Vec3& n, const Vec3& u, double dt) {
  const double nx = n.x(), ny = n.y(), nz = n.z();
  const double ux = u.x(), uy = u.y(), uz = u.z();
#pragma omp simd
  for (int k = 0; k < m; ++k) {
    const double delta = b.delta[k];
    const double s = -(b.r[k] - 0.5 * delta);
    const double ax = s * nx, ay = s * ny, az = s * nz;
    // vrel = v + w x a - u
    const double vx = b.vx[k] + (b.wy[k] * az - b.wz[k] * ay) - ux;
    const double vy = b.vy[k] + (b.wz[k] * ax - b.wx[k] * az) - uy;
    const double vz = b.vz[k] + (b.wx[k] * ay - b.wy[k] * ax) - uz;
    const double vn = vx * nx + vy * ny + vz * nz;
    const double vtx = vx - vn * nx, vty = vy - vn * ny, vtz = vz - vn * nz;
    double fx, fy, fz;
    lane_or_idle(law, delta, b.r[k], std::sqrt(b.m[k]), nx, ny, nz, vn, vtx, vty, vtz, dt, b.xix[k], b.xiy[k], b.xiz[k],
                 fx, fy, fz);
    b.fx[k] = fx;
    b.fy[k] = fy;
    b.fz[k] = fz;
    b.tx[k] = ay * fz - az * fy;
    b.ty[k] = az * fx - ax * fz;
    b.tz[k] = ax * fy - ay * fx;
  }
}

// Positions and radii packed four to a particle (x, y, z, r), aligned, for touch_test's vector
// pass (a thread's scratch, remade each call); nullptr where there is no vector pass.
const double* packed_positions([[maybe_unused]] const Vec3* x, [[maybe_unused]] const double* r,
                               [[maybe_unused]] std::size_t n) {
#ifdef HS_PAIR_GATHER_AVX512
  thread_local std::vector<double, Eigen::aligned_allocator<double>> packed;
  packed.resize(4 * n);
  double* __restrict xr = packed.data();
  for (std::size_t i = 0; i < n; ++i) {
    xr[4 * i] = x[i].x();
    xr[4 * i + 1] = x[i].y();
    xr[4 * i + 2] = x[i].z();
    xr[4 * i + 3] = r[i];
  }
  return xr;
#else
  return nullptr;
#endif
}

// 1a of the pair kernel: which of the block's len pairs (from p0) touch, with no branches. The
// touching ones go to b.pair (m of them) with their separation and radii (written at lane m
// whether or not the pair touches; a pair apart is overwritten by the next), the others to
// apart (z of them; the caller clears their springs). With AVX-512, eight pairs at a time:
// positions and radii from the packed copy xr, transposed into lanes, the touching lanes
// compressed to the lists' ends; the scalar loop does the rest (and all of it without AVX-512).
inline void touch_test(Block& b, std::uint32_t* apart, const ContactPair* pairs, std::size_t p0, int len,
                       const Vec3* x, const double* r, [[maybe_unused]] const double* xr, int& m, int& z) {
  int q = 0;
#ifdef HS_PAIR_GATHER_AVX512
  // eight pairs at a time from the packed (x, y, z, r) copy; the same sums as the scalar loop
  for (; q + kLanes <= len; q += kLanes) {
    const ContactPair* P = pairs + p0 + q;
    __m256d a[8], c[8];
    for (int l = 0; l < 8; ++l) {
      a[l] = _mm256_loadu_pd(xr + 4 * std::size_t{P[l].i});  // (aligned rows; loadu costs nothing then)
      c[l] = _mm256_loadu_pd(xr + 4 * std::size_t{P[l].j});
    }
    __m512d Xi, Yi, Zi, Ri, Xj, Yj, Zj, Rj;
    transpose8x4(a, Xi, Yi, Zi, Ri);
    transpose8x4(c, Xj, Yj, Zj, Rj);
    const __m512d DX = _mm512_sub_pd(Xj, Xi), DY = _mm512_sub_pd(Yj, Yi), DZ = _mm512_sub_pd(Zj, Zi);
    const __m512d RS = _mm512_add_pd(Ri, Rj);
    // (dx dx + dy dy) + dz dz: the sum the scalar loop's d.squaredNorm() makes, so both decide
    // alike which pairs touch
    const __m512d xx = _mm512_mul_pd(DX, DX), yy = _mm512_mul_pd(DY, DY);
    const __m512d d2 = _mm512_add_pd(_mm512_mul_pd(DZ, DZ), _mm512_add_pd(xx, yy));
    const __mmask8 touch = _mm512_cmp_pd_mask(d2, _mm512_mul_pd(RS, RS), _CMP_LT_OQ);
    const __m256i idx = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(p0 + q)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    _mm512_storeu_pd(b.dx + m, _mm512_maskz_compress_pd(touch, DX));
    _mm512_storeu_pd(b.dy + m, _mm512_maskz_compress_pd(touch, DY));
    _mm512_storeu_pd(b.dz + m, _mm512_maskz_compress_pd(touch, DZ));
    _mm512_storeu_pd(b.ri + m, _mm512_maskz_compress_pd(touch, Ri));
    _mm512_storeu_pd(b.rj + m, _mm512_maskz_compress_pd(touch, Rj));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(b.pair + m), _mm256_maskz_compress_epi32(touch, idx));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(apart + z), _mm256_maskz_compress_epi32(static_cast<__mmask8>(~touch), idx));
    const int nt = __builtin_popcount(touch);
    m += nt;
    z += 8 - nt;
  }
#endif
  for (; q < len; ++q) {
    const ContactPair& p = pairs[p0 + q];
    const std::uint32_t i = p.i, j = p.j;
    const double ri = r[i], rj = r[j];
    const double rs = ri + rj;
    const Vec3 d = x[j] - x[i];
    const bool touch = d.squaredNorm() < rs * rs;
    b.dx[m] = d.x(); b.dy[m] = d.y(); b.dz[m] = d.z();
    b.ri[m] = ri; b.rj[m] = rj;
    b.pair[m] = static_cast<std::uint32_t>(p0 + q);
    m += touch ? 1 : 0;
    apart[z] = static_cast<std::uint32_t>(p0 + q);
    z += touch ? 0 : 1;
  }
}

// 1b of the pair kernel: the touching pairs' relative velocity dv = v_j - v_i, spins, springs and
// sqrt(m_eff) into the block's lanes 0..m-1. With AVX-512 eight pairs at a time: each pair's
// vectors as rows (the same subtraction, so the same dv), transposed into lanes.
inline void gather_motion(Block& b, int m, const ContactPair* pairs, const Vec3* v, const Vec3* w,
                          const double* smeff) {
  int k = 0;
#ifdef HS_PAIR_GATHER_AVX512
  for (; k + kLanes <= m; k += kLanes) {
    __m256d dv[8], wi[8], wj[8], xi[8];
    for (int l = 0; l < 8; ++l) {
      const ContactPair& p = pairs[b.pair[k + l]];
      dv[l] = _mm256_sub_pd(load3(v[p.j].data()), load3(v[p.i].data()));
      wi[l] = load3(w[p.i].data());
      wj[l] = load3(w[p.j].data());
      xi[l] = load3(p.xi.data());
      b.smeff[k + l] = smeff[b.pair[k + l]];
    }
    store_columns(dv, b.dvx + k, b.dvy + k, b.dvz + k);
    store_columns(wi, b.wix + k, b.wiy + k, b.wiz + k);
    store_columns(wj, b.wjx + k, b.wjy + k, b.wjz + k);
    store_columns(xi, b.xix + k, b.xiy + k, b.xiz + k);
  }
#endif
  for (; k < m; ++k) {
    const ContactPair& p = pairs[b.pair[k]];
    const std::uint32_t i = p.i, j = p.j;
    b.smeff[k] = smeff[b.pair[k]];
    const Vec3 dv = v[j] - v[i];
    b.dvx[k] = dv.x(); b.dvy[k] = dv.y(); b.dvz[k] = dv.z();
    b.wix[k] = w[i].x(); b.wiy[k] = w[i].y(); b.wiz[k] = w[i].z();
    b.wjx[k] = w[j].x(); b.wjy[k] = w[j].y(); b.wjz[k] = w[j].z();
    b.xix[k] = p.xi.x(); b.xiy[k] = p.xi.y(); b.xiz[k] = p.xi.z();
  }
}

// 3 of the pair kernel: the block's forces and torques onto the particles and its springs back
// into the list, pair by pair in list order. The force and torque of the particle whose pairs are
// being scattered stay in registers while its pairs follow one another in the list (j != i in
// every pair, so no other write reaches them); the sums are the same, in the same order, as
// adding to memory each time. (Tried with AVX-512, a pair's three components as one masked
// vector: 15 % slower; a masked or 32-byte store does not forward to the next pair's load of a
// neighbouring particle 24 bytes on.)
class Scatter {
 public:
  Scatter(Vec3* f, Vec3* t) : f_(f), t_(t) {}
  void block(const Block& b, int m, ContactPair* pairs) {
    for (int k = 0; k < m; ++k) {
      ContactPair& p = pairs[b.pair[k]];
      const std::uint32_t i = p.i, j = p.j;
      p.xi = Vec3(b.xix[k], b.xiy[k], b.xiz[k]);
      if (i != cur_) {
        finish();
        cur_ = i;
        fcur_ = f_[i];
        tcur_ = t_[i];
      }
      const Vec3 F(b.fx[k], b.fy[k], b.fz[k]);
      f_[j] += F;
      fcur_ -= F;
      tcur_ -= Vec3(b.tix[k], b.tiy[k], b.tiz[k]);
      t_[j] += Vec3(b.tjx[k], b.tjy[k], b.tjz[k]);
    }
  }
  // the current particle's sums back to memory
  void finish() {
    if (cur_ == kNoParticle) return;
    f_[cur_] = fcur_;
    t_[cur_] = tcur_;
  }

 private:
  static constexpr std::uint32_t kNoParticle = 0xffffffffu;
  Vec3* __restrict f_;
  Vec3* __restrict t_;
  std::uint32_t cur_ = kNoParticle;
  Vec3 fcur_ = Vec3::Zero(), tcur_ = Vec3::Zero();
};

}  // namespace

const double* Engine::pair_smeff() {
  // sqrt(m_eff) of each pair, m_eff = 1 / (1/m_i + 1/m_j) (0 for two immovable particles): made
  // at each neighbour rebuild (pairs_smeff_ cleared there), extended for pairs added since
  // (broken bonds); masses do not change.
  const double* im = ps_.inv_mass.data();
  if (pair_smeff_.size() > pairs_.size()) pair_smeff_.clear();
  for (std::size_t k = pair_smeff_.size(); k < pairs_.size(); ++k) {
    const double s = im[pairs_[k].i] + im[pairs_[k].j];
    pair_smeff_.push_back(s > 0.0 ? std::sqrt(1.0 / s) : 0.0);
  }
  return pair_smeff_.data();
}

template <class Law>
void Engine::pair_kernel_impl(const Law& law) {
  Vec3* __restrict f = ps_.f.data();
  Vec3* __restrict t = ps_.torque.data();
  const Vec3* x = ps_.x.data();
  const Vec3* v = ps_.v.data();
  const Vec3* w = ps_.omega.data();
  const double* r = ps_.radius.data();
  const double dt = history_dt_;
  double worst = 0.0;
  std::uint32_t wi = 0, wj = 0;
  thread_local Block b;
  const double* smeff = pair_smeff();
  std::uint32_t apart[kList];
  const double* xr = packed_positions(x, r, ps_.size());
  const std::size_t np = pairs_.size();
  ContactPair* pairs = pairs_.data();
  Scatter scatter(f, t);
  for (std::size_t p0 = 0; p0 < np; p0 += kBlock) {
    const int len = static_cast<int>(std::min<std::size_t>(kBlock, np - p0));
    // 1a. which pairs touch (touch_test)
    int m = 0, z = 0;
    touch_test(b, apart, pairs, p0, len, x, r, xr, m, z);
    // contact over: the spring goes (only a non-zero one is written: most pairs apart were apart
    // before, and a spring of signed zeros stays as it is, as in the scalar pass)
    for (int k = 0; k < z; ++k) {
      Vec3& xi = pairs[apart[k]].xi;
      if ((xi.x() != 0.0) | (xi.y() != 0.0) | (xi.z() != 0.0)) xi.setZero();
    }
    // 1b. the touching pairs' motion and springs
    gather_motion(b, m, pairs, v, w, smeff);
    // 1c. the lanes up to the next multiple of kLanes compute an idle pair (two immovable
    // particles, smeff = 0: no force, whatever their other inputs, which are what earlier blocks
    // left there; nothing of these lanes is scattered), so that the law never runs its scalar
    // remainder
    const int mpad = (m + kLanes - 1) / kLanes * kLanes;
    for (int k = m; k < mpad; ++k) {
      b.dx[k] = 1.0; b.dy[k] = 0.0; b.dz[k] = 0.0;
      b.ri[k] = 1.0; b.rj[k] = 1.0;  // (finite radii: no NaN in the idle lanes' sums)
      b.smeff[k] = 0.0;
    }
    // 2. the law, all lanes alike
    block_law(b, mpad, law, dt);
    // 3. scatter in list order
    scatter.block(b, m, pairs);
    // 4. the deepest overlap so far, in list order: the block is scanned only when one of its
    // lanes beats it (rarely, once the first blocks have set it)
    int deeper = 0;
#pragma omp simd reduction(| : deeper)
    for (int k = 0; k < m; ++k) deeper |= b.delta[k] > worst * std::min(b.ri[k], b.rj[k]) ? 1 : 0;
    if (deeper != 0)
      for (int k = 0; k < m; ++k) {
        const double rmin = std::min(b.ri[k], b.rj[k]);
        if (b.delta[k] > worst * rmin) {  // overlap ratio delta / rmin > worst
          worst = b.delta[k] / rmin;
          wi = pairs[b.pair[k]].i;
          wj = pairs[b.pair[k]].j;
        }
      }
  }
  scatter.finish();
  if (worst > worst_overlap_ratio_) {
    worst_overlap_ratio_ = worst;
    worst_overlap_i_ = wi;
    worst_overlap_j_ = wj;
    worst_overlap_source_ = -1;
  }
}


void Engine::pair_kernel(const LinearLaw& law) { pair_kernel_impl(law); }

void Engine::pair_kernel(const HertzLaw& law) { pair_kernel_impl(law); }

bool Engine::wall_kernel() {
  return with_contact_law(def_, [&](const auto& law) {
    using L = std::decay_t<decltype(law)>;
    if constexpr (std::is_same_v<L, LinearLaw> || std::is_same_v<L, HertzLaw>) {
      wall_kernel_impl(law);
      return true;
    } else {
      return false;  // a law without a vectorised kernel: wall_forces' scalar loop
    }
  });
}

template <class Law>
void Engine::wall_kernel_impl(const Law& particle_law) {
  const Vec3* x = ps_.x.data();
  const Vec3* v = ps_.v.data();
  const Vec3* w = ps_.omega.data();
  Vec3* __restrict f = ps_.f.data();
  Vec3* __restrict t = ps_.torque.data();
  thread_local WallBlock b;
  for (std::size_t k = 0; k < walls_.size(); ++k) {
    const PlaneWall& wall = walls_[k];
    const Law law = particle_law.with_friction(wall.friction);
    Vec3* hist = wall_hist_[k].data();
    const std::vector<std::uint32_t>& cand = wall_cand_[k];
    Vec3 total = Vec3::Zero();
    for (std::size_t c0 = 0; c0 < cand.size(); c0 += kBlock) {
      const std::size_t c1 = std::min(cand.size(), c0 + kBlock);
      // 1. gather the touching candidates (a candidate apart has its spring cleared)
      int m = 0;
      for (std::size_t c = c0; c < c1; ++c) {
        const std::uint32_t i = cand[c];
        const double r = ps_.radius[i];
        const double dist = (x[i] - wall.point).dot(wall.normal);
        if (dist >= r) {
          hist[i].setZero();
          continue;
        }
        if (ps_.inv_mass[i] == 0.0) continue;
        b.particle[m] = i;
        b.delta[m] = r - dist;
        b.r[m] = r;
        b.m[m] = ps_.mass[i];
        b.vx[m] = v[i].x(); b.vy[m] = v[i].y(); b.vz[m] = v[i].z();
        b.wx[m] = w[i].x(); b.wy[m] = w[i].y(); b.wz[m] = w[i].z();
        b.xix[m] = hist[i].x(); b.xiy[m] = hist[i].y(); b.xiz[m] = hist[i].z();
        ++m;
      }
      // idle lanes up to a multiple of kLanes (m = 0: no force; finite inputs)
      const int mpad = (m + kLanes - 1) / kLanes * kLanes;
      for (int l = m; l < mpad; ++l) {
        b.delta[l] = 0.0; b.r[l] = 1.0; b.m[l] = 0.0;
      }
      // 2. the law
      wall_block_law(b, mpad, law, wall.normal, wall.velocity, history_dt_);
      // 3. scatter in candidate order
      for (int l = 0; l < m; ++l) {
        const std::uint32_t i = b.particle[l];
        const Vec3 F(b.fx[l], b.fy[l], b.fz[l]);
        f[i] += F;
        t[i] += Vec3(b.tx[l], b.ty[l], b.tz[l]);
        total -= F;
        hist[i] = Vec3(b.xix[l], b.xiy[l], b.xiz[l]);
        if (b.delta[l] / b.r[l] > worst_overlap_ratio_) {
          worst_overlap_ratio_ = b.delta[l] / b.r[l];
          worst_overlap_i_ = i;
          worst_overlap_j_ = ParticleStore::kNone - 1 - static_cast<std::uint32_t>(k);  // plane wall k
        }
      }
    }
    wall_force_[k] = total;
  }
}

}  // namespace hs::bonded

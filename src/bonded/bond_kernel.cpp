// In a build without AVX, GCC notes that 32-byte vectors passed by value would change the ABI:
// all of them stay inside this file (anonymous namespace), so there is no ABI to change. First
// line, so that it also covers the header templates this file instantiates.
#pragma GCC diagnostic ignored "-Wpsabi"

#include "bond_kernel.h"

#include "engine.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <stdexcept>

#if defined(__AVX__)
#include <immintrin.h>
#endif

namespace hs::bonded {

void BondBatch::pack(const std::vector<Bond>& bonds) {
  n_ = bonds.size();
  size_arrays();
  for (std::size_t k = 0; k < n_; ++k) {
    const Bond& b = bonds[k];
    i[k] = b.i;
    j[k] = b.j;
    kind[k] = static_cast<std::uint8_t>(b.kind);
    rix[k] = b.ref.ri.x(); riy[k] = b.ref.ri.y(); riz[k] = b.ref.ri.z();
    rjx[k] = b.ref.rj.x(); rjy[k] = b.ref.rj.y(); rjz[k] = b.ref.rj.z();
    cw[k] = b.ref.c.w(); cx[k] = b.ref.c.x(); cy[k] = b.ref.c.y(); cz[k] = b.ref.c.z();
    strength[k] = b.strength;
  }
  finish(0);
}

namespace {

/// Erases a[gone[k].index] from a's first n elements, keeping the order of the others: each run
/// between two erased elements moves down once.
template <class T>
void erase_sorted(std::vector<T>& a, std::size_t n, const std::vector<BrokenBond>& gone) {
  std::size_t w = gone.front().index;
  for (std::size_t k = 0; k < gone.size(); ++k) {
    const std::size_t from = gone[k].index + 1, to = k + 1 < gone.size() ? gone[k + 1].index : n;
    std::copy(a.begin() + from, a.begin() + to, a.begin() + w);
    w += to - from;
  }
}

}  // namespace

void BondBatch::erase(const std::vector<BrokenBond>& gone) {
  if (gone.empty()) return;
  assert(valid_ && gone.back().index < n_);
  assert(std::adjacent_find(gone.begin(), gone.end(), [](const BrokenBond& a, const BrokenBond& b) {
           return a.index >= b.index;
         }) == gone.end() && "strictly ascending indices");
  for (auto* a : {&i, &j}) erase_sorted(*a, n_, gone);
  erase_sorted(kind, n_, gone);
  for (auto* a : {&rix, &riy, &riz, &rjx, &rjy, &rjz, &cw, &cx, &cy, &cz, &strength}) erase_sorted(*a, n_, gone);
  n_ -= gone.size();
  size_arrays();
  finish(gone.front().index / kLanes);
}

void BondBatch::size_arrays() {
  const std::size_t padded = (n_ + kLanes - 1) / kLanes * kLanes;
  for (auto* a : {&i, &j}) a->resize(padded);
  kind.resize(padded);
  for (auto* a : {&rix, &riy, &riz, &rjx, &rjy, &rjz, &cw, &cx, &cy, &cz, &strength}) a->resize(padded);
}

void BondBatch::finish(std::size_t first_batch) {
  // Padding lanes repeat the last bond: finite data whose results are dropped.
  for (std::size_t k = n_; k < padded(); ++k) {
    i[k] = i[n_ - 1]; j[k] = j[n_ - 1]; kind[k] = kind[n_ - 1];
    rix[k] = rix[n_ - 1]; riy[k] = riy[n_ - 1]; riz[k] = riz[n_ - 1];
    rjx[k] = rjx[n_ - 1]; rjy[k] = rjy[n_ - 1]; rjz[k] = rjz[n_ - 1];
    cw[k] = cw[n_ - 1]; cx[k] = cx[n_ - 1]; cy[k] = cy[n_ - 1]; cz[k] = cz[n_ - 1];
    strength[k] = strength[n_ - 1];
  }
  batch_kind.resize(padded() / kLanes);
  for (std::size_t g = first_batch; g < batch_kind.size(); ++g) {
    std::uint8_t k0 = kind[g * kLanes];
    for (std::size_t l = 1; l < kLanes; ++l)
      if (kind[g * kLanes + l] != k0) k0 = 0xff;
    batch_kind[g] = k0;
  }
  valid_ = true;
}

namespace {

constexpr std::size_t W = BondBatch::kLanes;
using vd = double __attribute__((vector_size(W * sizeof(double))));
using vm = std::int64_t __attribute__((vector_size(W * sizeof(double))));  // lane masks of comparisons

inline vd splat(double s) { return vd{} + s; }

inline vd load(const double* p) {
  vd r;
  std::memcpy(&r, p, sizeof r);
  return r;
}

template <class V>
inline V vsqrt(V a) {
#if defined(__AVX512F__)
  if constexpr (sizeof(V) == 64) return _mm512_sqrt_pd(a); else
#endif
#if defined(__AVX__)
  if constexpr (sizeof(V) == 32) return _mm256_sqrt_pd(a); else
#endif
  {
    V r;
    for (std::size_t l = 0; l < sizeof(V) / sizeof(double); ++l) r[l] = std::sqrt(a[l]);
    return r;
  }
}

inline vd vabs(vd a) {
  vd r;
  for (std::size_t l = 0; l < W; ++l) r[l] = std::fabs(a[l]);
  return r;
}

/// Lane l of the vector: base[stride * idx[l] + off] (a gather from an array of structures).
inline vd gather(const double* base, const std::uint32_t* idx, std::size_t stride, std::size_t off) {
  vd r;
  for (std::size_t l = 0; l < W; ++l) r[l] = base[stride * idx[l] + off];
  return r;
}

struct V3 {
  vd x, y, z;
};
inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator-(const V3& a) { return {-a.x, -a.y, -a.z}; }
inline V3 operator*(vd s, const V3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline V3 operator*(double s, const V3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline vd dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

struct VQ {
  vd w, x, y, z;
};
/// Hamilton product a b.
inline VQ mul(const VQ& a, const VQ& b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y + a.y * b.w + a.z * b.x - a.x * b.z, a.w * b.z + a.z * b.w + a.x * b.y - a.y * b.x};
}
/// q v q^* for a unit quaternion, in the form Eigen uses: v + w t + q.vec x t, t = 2 q.vec x v.
inline V3 rotate(const VQ& q, const V3& v) {
  const V3 qv{q.x, q.y, q.z};
  const V3 c = cross(qv, v);
  const V3 t{c.x + c.x, c.y + c.y, c.z + c.z};
  return v + q.w * t + cross(qv, t);
}

/// Per-lane parameters of a batch.
struct VParams {
  vd kn, ks, kb, kt, gn, gs, gb, gt, sps, spb, tps, tpt, sc, tc;
  bool damped;
};

VParams uniform_params(const ParallelBondParams& p) {
  return {splat(p.kn), splat(p.ks), splat(p.kb), splat(p.kt), splat(p.gamma_n), splat(p.gamma_s),
          splat(p.gamma_b), splat(p.gamma_t), splat(p.sigma_per_stretch), splat(p.sigma_per_bend),
          splat(p.tau_per_slide), splat(p.tau_per_twist), splat(p.sigma_c), splat(p.tau_c),
          p.gamma_n > 0.0 || p.gamma_s > 0.0 || p.gamma_b > 0.0 || p.gamma_t > 0.0};
}

VParams mixed_params(const ParallelBondParams* params, const std::uint8_t* kind) {
  VParams v{};
  v.damped = false;
  for (std::size_t l = 0; l < W; ++l) {
    const ParallelBondParams& p = params[kind[l]];
    v.kn[l] = p.kn; v.ks[l] = p.ks; v.kb[l] = p.kb; v.kt[l] = p.kt;
    v.gn[l] = p.gamma_n; v.gs[l] = p.gamma_s; v.gb[l] = p.gamma_b; v.gt[l] = p.gamma_t;
    v.sps[l] = p.sigma_per_stretch; v.spb[l] = p.sigma_per_bend;
    v.tps[l] = p.tau_per_slide; v.tpt[l] = p.tau_per_twist;
    v.sc[l] = p.sigma_c; v.tc[l] = p.tau_c;
    v.damped = v.damped || p.gamma_n > 0.0 || p.gamma_s > 0.0 || p.gamma_b > 0.0 || p.gamma_t > 0.0;
  }
  return v;
}

/// One batch's results.
struct Out {
  V3 fj, ti, tj;
  vd sigma, tau, crush;
  vm exact;  ///< lane needs the scalar law (rotation beyond the series' range)
};

inline Out batch(const BondBatch& bb, std::size_t k0, const VParams& p, const BondKernelIo& io) {
  const std::uint32_t* ii = bb.i.data() + k0;
  const std::uint32_t* jj = bb.j.data() + k0;
  const double* X = io.x[0].data();
  const double* Q = io.q[0].coeffs().data();  // x, y, z, w
  const V3 xi{gather(X, ii, 3, 0), gather(X, ii, 3, 1), gather(X, ii, 3, 2)};
  const V3 xj{gather(X, jj, 3, 0), gather(X, jj, 3, 1), gather(X, jj, 3, 2)};
  const VQ qi{gather(Q, ii, 4, 3), gather(Q, ii, 4, 0), gather(Q, ii, 4, 1), gather(Q, ii, 4, 2)};
  const VQ qj{gather(Q, jj, 4, 3), gather(Q, jj, 4, 0), gather(Q, jj, 4, 1), gather(Q, jj, 4, 2)};
  const V3 ri{load(&bb.rix[k0]), load(&bb.riy[k0]), load(&bb.riz[k0])};
  const V3 rj{load(&bb.rjx[k0]), load(&bb.rjy[k0]), load(&bb.rjz[k0])};
  const VQ c{load(&bb.cw[k0]), load(&bb.cx[k0]), load(&bb.cy[k0]), load(&bb.cz[k0])};

  Out o;
  const V3 ai = rotate(qi, ri);
  const V3 aj = rotate(qj, rj);
  const V3 d = xj - xi;
  const vd invL = 1.0 / vsqrt(dot(d, d));
  const V3 n = invL * d;

  // --- translation ---
  const V3 u = d + aj - ai;
  const vd un = dot(u, n);
  const V3 us = u - un * n;
  const V3 fu = (p.kn * un) * n + p.ks * us;

  // --- rotation: W = q_j c q_i^*, theta = log(W) by the series of rotation_vector ---
  const VQ qic{qi.w, -qi.x, -qi.y, -qi.z};
  const VQ w = mul(mul(qj, c), qic);
  // rotation_vector first turns W to w >= 0 (the shortest arc); the series below gives the same
  // bits when W.vec and W.w both change sign ((2/(-c)) (-v) = (2/c) v exactly), so no turn here.
  const V3 wv{w.x, w.y, w.z};
  const vd s2 = dot(wv, wv);
  const vd ic = 1.0 / w.w;
  const vd t2 = s2 * ic * ic;
  constexpr double k3 = 1.0 / 3.0, k5 = 1.0 / 5.0, k7 = 1.0 / 7.0;
  const V3 th = ((2.0 * ic) * (1.0 - t2 * (k3 - t2 * (k5 - t2 * k7)))) * wv;
  const vd thn = dot(th, n);
  const V3 ths = th - thn * n;
  const V3 g = p.kb * th + ((p.kt - p.kb) * thn) * n;
  const vd phi2 = dot(th, th);
  const vd c2 = log_jacobian_c2_series(phi2);
  o.exact = ~(t2 < kRotationSeriesT2) | ~(phi2 < kLogJacobianSeriesPhi2);  // NaN too, as in parallel_bond
  const V3 txg = cross(th, g);
  const V3 txtxg = cross(th, txg);

  V3 dn = ((p.kn - p.ks) * un) * u + ((p.kt - p.kb) * thn) * th;
  dn = dn - dot(dn, n) * n;

  const V3 h = 0.5 * txg;
  const V3 cc = c2 * txtxg;
  o.fj = -fu - invL * dn;
  o.ti = cross(ai, fu) + (g - h + cc);
  o.tj = -cross(aj, fu) - (g + h + cc);

  // --- damping, applied at the mid-point of the two bond-centre points ---
  if (p.damped) {
    const V3 vi{gather(io.v[0].data(), ii, 3, 0), gather(io.v[0].data(), ii, 3, 1), gather(io.v[0].data(), ii, 3, 2)};
    const V3 vj{gather(io.v[0].data(), jj, 3, 0), gather(io.v[0].data(), jj, 3, 1), gather(io.v[0].data(), jj, 3, 2)};
    const double* Om = io.omega[0].data();
    const V3 wi{gather(Om, ii, 3, 0), gather(Om, ii, 3, 1), gather(Om, ii, 3, 2)};
    const V3 wj{gather(Om, jj, 3, 0), gather(Om, jj, 3, 1), gather(Om, jj, 3, 2)};
    const V3 vrel = (vj + cross(wj, aj)) - (vi + cross(wi, ai));
    const vd vn = dot(vrel, n);
    const V3 fd = -((p.gn * vn) * n + p.gs * (vrel - vn * n));
    const V3 mid_i = ai + 0.5 * u;
    const V3 mid_j = mid_i - d;
    const V3 wrel = wj - wi;
    const vd wn = dot(wrel, n);
    const V3 md = -((p.gt * wn) * n + p.gb * (wrel - wn * n));
    o.fj = o.fj + fd;
    o.ti = o.ti + cross(mid_i, -fd) - md;
    o.tj = o.tj + cross(mid_j, fd) + md;
  }

  const vd bend = p.spb * vsqrt(dot(ths, ths));
  o.sigma = p.sps * un + bend;
  o.crush = bend - p.sps * un;
  o.tau = p.tps * vsqrt(dot(us, us)) + p.tpt * vabs(thn);
  return o;
}

}  // namespace

void bond_kernel(const BondBatch& bb, const ParallelBondParams* params, std::size_t n_params, const BondKernelIo& io,
                 std::vector<BrokenBond>& broken) {
  const std::size_t n = bb.size();
  if (n == 0) return;
  for (std::size_t k = 0; k < n; ++k)
    if (bb.kind[k] >= n_params) throw std::logic_error("bond_kernel: bond of an unknown kind");
  VParams uni[2];
  for (std::size_t k = 0; k < n_params && k < 2; ++k) uni[k] = uniform_params(params[k]);
  Vec3* f = io.f;
  Vec3* t = io.torque;
  for (std::size_t k0 = 0; k0 < n; k0 += W) {
    const std::uint8_t bk = bb.batch_kind[k0 / W];
    const VParams p = bk < 2 ? uni[bk] : mixed_params(params, &bb.kind[k0]);
    const Out o = batch(bb, k0, p, io);
    const std::size_t lanes = std::min(W, n - k0);
    for (std::size_t l = 0; l < lanes; ++l) {
      const std::size_t k = k0 + l;
      const std::uint32_t i = bb.i[k], j = bb.j[k];
      const ParallelBondParams& pk = params[bb.kind[k]];
      Vec3 fj, ti, tj;
      double sigma, tau, crush;
      if (o.exact[l]) {  // a large rotation: the scalar law with its exact log map
        const BondRef ref{Vec3(bb.rix[k], bb.riy[k], bb.riz[k]), Vec3(bb.rjx[k], bb.rjy[k], bb.rjz[k]),
                          Quat(bb.cw[k], bb.cx[k], bb.cy[k], bb.cz[k])};
        const BondKinematics kin{io.x[i], io.x[j], io.q[i], io.q[j], io.v[i], io.v[j], io.omega[i], io.omega[j]};
        const BondResult r = parallel_bond(pk, ref, kin);
        fj = r.fj; ti = r.ti; tj = r.tj; sigma = r.sigma; tau = r.tau; crush = r.crush;
      } else {
        fj = Vec3(o.fj.x[l], o.fj.y[l], o.fj.z[l]);
        ti = Vec3(o.ti.x[l], o.ti.y[l], o.ti.z[l]);
        tj = Vec3(o.tj.x[l], o.tj.y[l], o.tj.z[l]);
        sigma = o.sigma[l];
        tau = o.tau[l];
        crush = o.crush[l];
      }
      const BondFailure mode = bond_failure(pk, sigma, tau, crush, bb.strength[k]);
      if (mode != BondFailure::None) {
        broken.push_back({static_cast<std::uint32_t>(k), mode});
        continue;
      }
      f[j] += fj;
      f[i] -= fj;
      t[i] += ti;
      t[j] += tj;
    }
  }
}

}  // namespace hs::bonded

// The orientation update of Engine::step, four particles at a time (integrate_kernel.h,
// rotate_orientations).
//
// Each particle's update is rotate_orientation's series branch (integrate_kernel.cpp), lane by
// lane: the same operations in the same order (the Hamilton product as Eigen 3.4 computes it, the
// norm as (x x + z z) + (y y + w w), then sqrt and four divisions). Nothing is fused (the build's
// -ffp-contract=off), so the result is bit-identical to the scalar function with any compiler
// (IntegrateKernel.Orientation* in tests/bonded/test_integrate_kernel.cpp); the scalar loop costs
// ~22 ns per particle, almost all of it the series' and the norm's divisions, which four lanes share.
//
// Which path a particle takes depends on its own data only (w = 0: unchanged; a rotation too large
// for the series: the scalar function), and the last n % 4 particles run through the same
// four-lane code padded with w = 0, so results do not depend on a particle's index, nor on the rank
// count.
#include "integrate_kernel.h"

#if defined(__AVX__)
#include <immintrin.h>
#define HS_ORIENTATION_AVX 1
#endif

namespace hs::bonded {

#ifdef HS_ORIENTATION_AVX
namespace {

inline void transpose4(__m256d& a, __m256d& b, __m256d& c, __m256d& d) {
  const __m256d t0 = _mm256_unpacklo_pd(a, b), t1 = _mm256_unpackhi_pd(a, b);
  const __m256d t2 = _mm256_unpacklo_pd(c, d), t3 = _mm256_unpackhi_pd(c, d);
  a = _mm256_permute2f128_pd(t0, t2, 0x20);
  b = _mm256_permute2f128_pd(t1, t3, 0x20);
  c = _mm256_permute2f128_pd(t0, t2, 0x31);
  d = _mm256_permute2f128_pd(t1, t3, 0x31);
}

/// Four consecutive particles: q[0..3] (Eigen's x, y, z, w order) rotated by w[0..3] dt.
inline void rotate4(Quat* q, const Vec3* w, double dt) {
  const double* W = w[0].data();
  const __m256d wx = _mm256_setr_pd(W[0], W[3], W[6], W[9]);
  const __m256d wy = _mm256_setr_pd(W[1], W[4], W[7], W[10]);
  const __m256d wz = _mm256_setr_pd(W[2], W[5], W[8], W[11]);
  const __m256d one = _mm256_set1_pd(1.0), half = _mm256_set1_pd(0.5);
  const __m256d vdt = _mm256_set1_pd(dt);
  // |w|^2, h2 = (|w| dt / 2)^2, and the series of rotate_orientation.
  const __m256d wn2 = _mm256_add_pd(_mm256_mul_pd(wz, wz), _mm256_add_pd(_mm256_mul_pd(wx, wx), _mm256_mul_pd(wy, wy)));
  const __m256d h2 = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(wn2, _mm256_set1_pd(0.25)), vdt), vdt);
  const __m256d h4 = _mm256_mul_pd(h2, h2), h6 = _mm256_mul_pd(h2, h4);
  const __m256d c = _mm256_sub_pd(_mm256_add_pd(_mm256_sub_pd(one, _mm256_mul_pd(h2, half)), _mm256_div_pd(h4, _mm256_set1_pd(24.0))),
                                  _mm256_div_pd(h6, _mm256_set1_pd(720.0)));
  const __m256d sin_series =
      _mm256_sub_pd(_mm256_add_pd(_mm256_sub_pd(one, _mm256_div_pd(h2, _mm256_set1_pd(6.0))), _mm256_div_pd(h4, _mm256_set1_pd(120.0))),
                    _mm256_div_pd(h6, _mm256_set1_pd(5040.0)));
  const __m256d s = _mm256_mul_pd(sin_series, _mm256_mul_pd(half, vdt));
  const __m256d sx = _mm256_mul_pd(s, wx), sy = _mm256_mul_pd(s, wy), sz = _mm256_mul_pd(s, wz);

  double* Q = q[0].coeffs().data();
  __m256d qx = _mm256_loadu_pd(Q), qy = _mm256_loadu_pd(Q + 4), qz = _mm256_loadu_pd(Q + 8), qw = _mm256_loadu_pd(Q + 12);
  transpose4(qx, qy, qz, qw);
  // r = dq q, dq = (c, s w).
  const __m256d cqx = _mm256_mul_pd(c, qx), cqy = _mm256_mul_pd(c, qy), cqz = _mm256_mul_pd(c, qz), cqw = _mm256_mul_pd(c, qw);
  const __m256d zqx = _mm256_mul_pd(sz, qx), zqy = _mm256_mul_pd(sz, qy), zqz = _mm256_mul_pd(sz, qz), zqw = _mm256_mul_pd(sz, qw);
  __m256d rx = _mm256_sub_pd(_mm256_add_pd(_mm256_mul_pd(qz, sy), cqx), _mm256_sub_pd(zqy, _mm256_mul_pd(qw, sx)));
  __m256d ry = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(qw, sy), cqy), _mm256_sub_pd(zqx, _mm256_mul_pd(qz, sx)));
  __m256d rz = _mm256_add_pd(_mm256_sub_pd(cqz, _mm256_mul_pd(sy, qx)), _mm256_add_pd(_mm256_mul_pd(qy, sx), zqw));
  __m256d rw = _mm256_sub_pd(_mm256_sub_pd(cqw, _mm256_mul_pd(sy, qy)), _mm256_add_pd(_mm256_mul_pd(qx, sx), zqz));
  // Normalised where the norm is positive (as Eigen's normalize()).
  const __m256d n2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(rx, rx), _mm256_mul_pd(rz, rz)),
                                   _mm256_add_pd(_mm256_mul_pd(ry, ry), _mm256_mul_pd(rw, rw)));
  const __m256d norm = _mm256_sqrt_pd(n2);
  const __m256d pos = _mm256_cmp_pd(n2, _mm256_setzero_pd(), _CMP_GT_OQ);
  rx = _mm256_blendv_pd(rx, _mm256_div_pd(rx, norm), pos);
  ry = _mm256_blendv_pd(ry, _mm256_div_pd(ry, norm), pos);
  rz = _mm256_blendv_pd(rz, _mm256_div_pd(rz, norm), pos);
  rw = _mm256_blendv_pd(rw, _mm256_div_pd(rw, norm), pos);
  transpose4(rx, ry, rz, rw);

  const int moved = _mm256_movemask_pd(_mm256_cmp_pd(wn2, _mm256_setzero_pd(), _CMP_NEQ_UQ));
  const int series = _mm256_movemask_pd(_mm256_cmp_pd(h2, _mm256_set1_pd(kOrientationSeriesH2), _CMP_LT_OQ));
  const __m256d r[4] = {rx, ry, rz, rw};
  for (int l = 0; l < 4; ++l) {
    if (!(moved >> l & 1)) continue;
    if (series >> l & 1)
      _mm256_storeu_pd(Q + 4 * l, r[l]);
    else
      rotate_orientation(q[l], w[l], dt);
  }
}

}  // namespace
#endif

void rotate_orientations(std::size_t n, Quat* q, const Vec3* w, double dt) {
#ifdef HS_ORIENTATION_AVX
  static_assert(sizeof(Quat) == 4 * sizeof(double) && sizeof(Vec3) == 3 * sizeof(double));
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) rotate4(q + i, w + i, dt);
  if (i < n) {  // the last n % 4, padded with w = 0 (left unchanged)
    Quat qt[4] = {Quat::Identity(), Quat::Identity(), Quat::Identity(), Quat::Identity()};
    Vec3 wt[4] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    for (std::size_t k = i; k < n; ++k) {
      qt[k - i] = q[k];
      wt[k - i] = w[k];
    }
    rotate4(qt, wt, dt);
    for (std::size_t k = i; k < n; ++k) q[k] = qt[k - i];
  }
#else
  for (std::size_t i = 0; i < n; ++i) rotate_orientation(q[i], w[i], dt);
#endif
}

}  // namespace hs::bonded

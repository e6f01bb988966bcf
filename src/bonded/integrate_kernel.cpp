// integrate_kernel.h
#include "integrate_kernel.h"

#include <cmath>

#if defined(__AVX512F__)
#include <immintrin.h>
#define HS_INTEGRATE_AVX512 1
#endif

namespace hs::bonded {

namespace {

// One particle of each pass, as the Vec3 loops of Engine::step wrote it; the vector paths below
// do the same arithmetic eight particles at a time.
inline double kick_drift_one(std::size_t i, double dt, double hdt, Vec3* x, Vec3* v, Vec3* w, Vec3* f, Vec3* t,
                             const double* im, const double* ii, const double* mass, const Vec3* x_build,
                             const Vec3& g) {
  v[i] += hdt * im[i] * f[i];
  w[i] += hdt * ii[i] * t[i];
  x[i] += dt * v[i];
  f[i] = mass[i] * g;
  t[i].setZero();
  return (x[i] - x_build[i]).squaredNorm();
}

inline double kick_one(std::size_t i, double hdt, Vec3* v, Vec3* w, const Vec3* f, const Vec3* t, const double* im,
                       const double* ii) {
  v[i] += hdt * im[i] * f[i];
  w[i] += hdt * ii[i] * t[i];
  return v[i].squaredNorm();
}

#ifdef HS_INTEGRATE_AVX512
// Eight particles' Vec3s are 24 packed doubles, three registers (q0, q1, q2). A per-particle
// scalar s[0..7] spread over them: (s0 s0 s0 s1 s1 s1 s2 s2), (s2 s3 s3 s3 s4 s4 s4 s5),
// (s5 s5 s6 s6 s6 s7 s7 s7).
struct Spread {
  __m512i i0 = _mm512_set_epi64(2, 2, 1, 1, 1, 0, 0, 0);
  __m512i i1 = _mm512_set_epi64(5, 4, 4, 4, 3, 3, 3, 2);
  __m512i i2 = _mm512_set_epi64(7, 7, 7, 6, 6, 6, 5, 5);
  void operator()(__m512d s, __m512d& a0, __m512d& a1, __m512d& a2) const {
    a0 = _mm512_permutexvar_pd(i0, s);
    a1 = _mm512_permutexvar_pd(i1, s);
    a2 = _mm512_permutexvar_pd(i2, s);
  }
};

// The squared lengths of eight packed Vec3s, one per lane.
inline __m512d squared_lengths(__m512d q0, __m512d q1, __m512d q2) {
  // x: elements 0 3 6 9 12 15 18 21; y: 1 4 7 10 13 16 19 22; z: 2 5 8 11 14 17 20 23
  const __m512d tx = _mm512_permutex2var_pd(q0, _mm512_set_epi64(0, 0, 15, 12, 9, 6, 3, 0), q1);
  const __m512d ty = _mm512_permutex2var_pd(q0, _mm512_set_epi64(0, 0, 0, 13, 10, 7, 4, 1), q1);
  const __m512d tz = _mm512_permutex2var_pd(q0, _mm512_set_epi64(0, 0, 0, 14, 11, 8, 5, 2), q1);
  const __m512d X = _mm512_permutex2var_pd(tx, _mm512_set_epi64(13, 10, 5, 4, 3, 2, 1, 0), q2);
  const __m512d Y = _mm512_permutex2var_pd(ty, _mm512_set_epi64(14, 11, 8, 4, 3, 2, 1, 0), q2);
  const __m512d Z = _mm512_permutex2var_pd(tz, _mm512_set_epi64(15, 12, 9, 4, 3, 2, 1, 0), q2);
  // (x x + y y) + z z, the sum the scalar tail's squaredNorm makes, so every particle's figure is
  // the same bits wherever it falls (vector body or tail: under MPI that depends on the rank's count)
  const __m512d xx = _mm512_mul_pd(X, X), yy = _mm512_mul_pd(Y, Y);
  return _mm512_add_pd(_mm512_mul_pd(Z, Z), _mm512_add_pd(xx, yy));
}

// The largest lane (GCC 12's _mm512_reduce_max_pd trips -Wuninitialized in its own header).
inline double max_lane(__m512d a) {
  alignas(64) double l[8];
  _mm512_store_pd(l, a);
  double m = l[0];
  for (int k = 1; k < 8; ++k) m = l[k] > m ? l[k] : m;
  return m;
}

// Half kicks of eight particles starting at i: v += hdt im f, w += hdt ii t (stored); the new
// velocities are returned in v0 v1 v2 (packed, as in memory).
inline void kick8(const Spread& spread, __m512d H, std::size_t i, Vec3* v, Vec3* w, const Vec3* f, const Vec3* t,
                  const double* im, const double* ii, __m512d& v0, __m512d& v1, __m512d& v2) {
  double* V = v[i].data();
  double* W = w[i].data();
  const double* F = f[i].data();
  const double* T = t[i].data();
  __m512d a0, a1, a2, b0, b1, b2;
  spread(_mm512_mul_pd(H, _mm512_loadu_pd(im + i)), a0, a1, a2);
  spread(_mm512_mul_pd(H, _mm512_loadu_pd(ii + i)), b0, b1, b2);
  v0 = _mm512_add_pd(_mm512_mul_pd(a0, _mm512_loadu_pd(F)), _mm512_loadu_pd(V));
  v1 = _mm512_add_pd(_mm512_mul_pd(a1, _mm512_loadu_pd(F + 8)), _mm512_loadu_pd(V + 8));
  v2 = _mm512_add_pd(_mm512_mul_pd(a2, _mm512_loadu_pd(F + 16)), _mm512_loadu_pd(V + 16));
  _mm512_storeu_pd(V, v0);
  _mm512_storeu_pd(V + 8, v1);
  _mm512_storeu_pd(V + 16, v2);
  _mm512_storeu_pd(W, _mm512_add_pd(_mm512_mul_pd(b0, _mm512_loadu_pd(T)), _mm512_loadu_pd(W)));
  _mm512_storeu_pd(W + 8, _mm512_add_pd(_mm512_mul_pd(b1, _mm512_loadu_pd(T + 8)), _mm512_loadu_pd(W + 8)));
  _mm512_storeu_pd(W + 16, _mm512_add_pd(_mm512_mul_pd(b2, _mm512_loadu_pd(T + 16)), _mm512_loadu_pd(W + 16)));
}
#endif

}  // namespace

double kick_drift(std::size_t n, double dt, double hdt, Vec3* x, Vec3* v, Vec3* w, Vec3* f, Vec3* t,
                  const double* im, const double* ii, const double* mass, const Vec3* x_build,
                  const Vec3& g) {
  double disp2 = 0.0;
  std::size_t i = 0;
#ifdef HS_INTEGRATE_AVX512
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  const Spread spread;
  const __m512d H = _mm512_set1_pd(hdt), DT = _mm512_set1_pd(dt);
  const __m512d G0 = _mm512_set_pd(g.y(), g.x(), g.z(), g.y(), g.x(), g.z(), g.y(), g.x());
  const __m512d G1 = _mm512_set_pd(g.x(), g.z(), g.y(), g.x(), g.z(), g.y(), g.x(), g.z());
  const __m512d G2 = _mm512_set_pd(g.z(), g.y(), g.x(), g.z(), g.y(), g.x(), g.z(), g.y());
  __m512d D2 = _mm512_setzero_pd();
  for (; i + 8 <= n; i += 8) {
    double* X = x[i].data();
    double* F = f[i].data();
    double* T = t[i].data();
    const double* XB = x_build[i].data();
    __m512d v0, v1, v2, m0, m1, m2;
    kick8(spread, H, i, v, w, f, t, im, ii, v0, v1, v2);
    spread(_mm512_loadu_pd(mass + i), m0, m1, m2);
    const __m512d x0 = _mm512_add_pd(_mm512_mul_pd(DT, v0), _mm512_loadu_pd(X));
    const __m512d x1 = _mm512_add_pd(_mm512_mul_pd(DT, v1), _mm512_loadu_pd(X + 8));
    const __m512d x2 = _mm512_add_pd(_mm512_mul_pd(DT, v2), _mm512_loadu_pd(X + 16));
    _mm512_storeu_pd(X, x0);
    _mm512_storeu_pd(X + 8, x1);
    _mm512_storeu_pd(X + 16, x2);
    // (max_pd returns its second operand when either is NaN: a NaN displacement is ignored, as
    // std::max(disp2, d2) did)
    D2 = _mm512_max_pd(squared_lengths(_mm512_sub_pd(x0, _mm512_loadu_pd(XB)),
                                       _mm512_sub_pd(x1, _mm512_loadu_pd(XB + 8)),
                                       _mm512_sub_pd(x2, _mm512_loadu_pd(XB + 16))),
                       D2);
    _mm512_storeu_pd(F, _mm512_mul_pd(m0, G0));
    _mm512_storeu_pd(F + 8, _mm512_mul_pd(m1, G1));
    _mm512_storeu_pd(F + 16, _mm512_mul_pd(m2, G2));
    const __m512d zero = _mm512_setzero_pd();
    _mm512_storeu_pd(T, zero);
    _mm512_storeu_pd(T + 8, zero);
    _mm512_storeu_pd(T + 16, zero);
  }
  disp2 = max_lane(D2);
#endif
  for (; i < n; ++i) {
    const double d2 = kick_drift_one(i, dt, hdt, x, v, w, f, t, im, ii, mass, x_build, g);
    disp2 = d2 > disp2 ? d2 : disp2;
  }
  return disp2;
}

double kick(std::size_t n, double hdt, Vec3* v, Vec3* w, const Vec3* f, const Vec3* t, const double* im,
            const double* ii) {
  double worst = 0.0;
  bool nan = false;
  std::size_t i = 0;
#ifdef HS_INTEGRATE_AVX512
  const Spread spread;
  const __m512d H = _mm512_set1_pd(hdt);
  __m512d M = _mm512_setzero_pd();
  __mmask8 bad = 0;
  for (; i + 8 <= n; i += 8) {
    __m512d v0, v1, v2;
    kick8(spread, H, i, v, w, f, t, im, ii, v0, v1, v2);
    const __m512d s = squared_lengths(v0, v1, v2);
    bad |= _mm512_cmp_pd_mask(s, s, _CMP_UNORD_Q);
    M = _mm512_max_pd(M, s);
  }
  worst = max_lane(M);
  nan = bad != 0;
#endif
  for (; i < n; ++i) {
    const double v2 = kick_one(i, hdt, v, w, f, t, im, ii);
    nan = nan || std::isnan(v2);
    worst = v2 > worst ? v2 : worst;
  }
  return nan ? std::nan("") : worst;
}

void rotate_orientation(Quat& q, const Vec3& w, double dt) {
  const double wn2 = w.squaredNorm();
  if (wn2 == 0.0) return;
  const double h2 = 0.25 * wn2 * dt * dt;  // (|w| dt / 2)^2
  double c, s;                             // cos(h), sin(h)/|w|
  if (h2 < kOrientationSeriesH2) {  // Taylor to h^6: error < 1e-19 at h = 1e-2
    c = 1.0 - h2 / 2.0 + h2 * h2 / 24.0 - h2 * h2 * h2 / 720.0;
    s = 0.5 * dt * (1.0 - h2 / 6.0 + h2 * h2 / 120.0 - h2 * h2 * h2 / 5040.0);
  } else {
    const double wn = std::sqrt(wn2);
    const double h = 0.5 * wn * dt;
    c = std::cos(h);
    s = std::sin(h) / wn;
  }
  const Quat dq(c, s * w.x(), s * w.y(), s * w.z());
  q = dq * q;
  q.normalize();
}

}  // namespace hs::bonded

// The velocity-Verlet integrator's two passes over the owned particles (Engine::step). With
// AVX-512 eight particles at a time (their Vec3s are 24 packed doubles, three registers); without
// it, and for the last n % 8, the Vec3 loops they replaced. Each particle's arithmetic is what
// the Vec3 loops do (nothing fused; squared lengths as (x x + y y) + z z), so the state and both
// maxima are bit-identical to those loops.
#pragma once

#include "common/types.h"

#include <cstddef>

namespace hs::bonded {

/// First half of a step for particles [0, n): v += hdt im f, w += hdt ii t, x += dt v; then the
/// forces start from gravity (f = m g) and the torques from zero. Returns the largest squared
/// displacement since the last rebuild (|x - x_build|^2; NaN ones ignored, as std::max did).
double kick_drift(std::size_t n, double dt, double hdt, Vec3* x, Vec3* v, Vec3* w, Vec3* f, Vec3* t,
                  const double* inv_mass, const double* inv_inertia, const double* mass, const Vec3* x_build,
                  const Vec3& gravity);

/// Second half: v += hdt im f, w += hdt ii t. Returns the largest v^2 (NaN if any particle's is).
double kick(std::size_t n, double hdt, Vec3* v, Vec3* w, const Vec3* f, const Vec3* t, const double* inv_mass,
            const double* inv_inertia);

/// Below this h2 = (|w| dt / 2)^2 the orientation update uses its series (error < 1e-19 at
/// h = 1e-2); above it, cos and sin.
constexpr double kOrientationSeriesH2 = 1e-4;

/// Rotates q by the world-frame rotation vector phi = w dt (exact exponential map), then
/// normalises it; w = 0 leaves q unchanged.
void rotate_orientation(Quat& q, const Vec3& w, double dt);

/// rotate_orientation for particles [0, n), four at a time where the target has AVX
/// (orientation_kernel.cpp): bit-identical to it.
void rotate_orientations(std::size_t n, Quat* q, const Vec3* w, double dt);

}  // namespace hs::bonded

// The velocity-Verlet integrator's two passes over the owned particles (Engine::step), written
// over the coordinates as flat arrays so that the compiler vectorises them (several particles per
// register; integrate_kernel.cpp is built with -fopenmp-simd). Each particle's arithmetic is
// what the Vec3 loops did (a product times a vector added with one fused multiply-add), so the
// state is bit-identical; only the rebuild measure's sum may round differently (below).
#pragma once

#include "common/types.h"

#include <cstddef>

namespace hs::bonded {

/// First half of a step for particles [0, n): v += hdt im f, w += hdt ii t, x += dt v; then the
/// forces start from gravity (f = m g) and the torques from zero. Returns the largest squared
/// displacement since the last rebuild (|x - x_build|^2; its sum is the vector loop's, which may
/// differ from Eigen's squaredNorm in the last bit: it only decides when to rebuild).
double kick_drift(std::size_t n, double dt, double hdt, Vec3* x, Vec3* v, Vec3* w, Vec3* f, Vec3* t,
                  const double* inv_mass, const double* inv_inertia, const double* mass, const Vec3* x_build,
                  const Vec3& gravity);

/// Second half: v += hdt im f, w += hdt ii t. Returns the largest v^2 (NaN if any particle's is).
double kick(std::size_t n, double hdt, Vec3* v, Vec3* w, const Vec3* f, const Vec3* t, const double* inv_mass,
            const double* inv_inertia);

}  // namespace hs::bonded

// The part every contact law shares, written once on plain doubles (one contact): the pair and
// wall kernels (contact_kernel.cpp) call it inside their vector loops, and each law's Vec3
// force() (contact_linear.h, contact_hertz.h) calls it too, so a contact computes the same bits
// in a kernel lane and in a scalar loop (mesh, block, crushed-bond contacts).
//
//   F_n  = f_el(delta) - gamma_n v_n                          (normal, along n, repulsive > 0)
//   xi  <- xi projected onto the tangent plane, its length kept, then + v_t dt
//   F_t  = -S_t xi - gamma_t v_t,   |F_t| <= mu max(F_n, 0)   (Coulomb cap; xi is rewound so
//          that the spring alone carries the capped force: xi = -(F_t + gamma_t v_t) / S_t)
//
// A law supplies f_el, S_t, 1/S_t (0 for no spring), gamma_n and gamma_t from the overlap delta,
// R* and sqrt(m_eff) (Law::lane_springs), and its friction coefficient (Law::friction()).
// Everything is branch-free so that the kernels vectorise it.
// Sign conventions: n from particle i to particle j (or from the wall to the particle), v_n the
// normal relative velocity of j w.r.t. i (positive when separating), v_t the tangential relative
// velocity of j's contact point w.r.t. i's. Output: the force on j.
#pragma once

#include "common/types.h"

#include <cmath>

namespace hs::bonded {

struct ContactResult {
  Vec3 force;  ///< on j, N
  double fn;   ///< signed normal force, N (repulsive > 0)
};

/// One contact on plain doubles: the force on j in (fx, fy, fz), the new spring in xi; returns
/// the signed normal force.
template <class Law>
[[gnu::always_inline]] inline double contact_lane(const Law& law, double delta, double rstar, double smeff, double nx,
                                                  double ny, double nz, double vn, double vtx, double vty, double vtz,
                                                  double dt, double& xi_x, double& xi_y, double& xi_z, double& fx,
                                                  double& fy, double& fz) {
  double fel, st, inv_st, gn, gt;
  law.lane_springs(delta, rstar, smeff, fel, st, inv_st, gn, gt);
  const double fn = fel - gn * vn;
  // spring history: onto the tangent plane keeping its length, then advanced by vt dt
  double xix = xi_x, xiy = xi_y, xiz = xi_z;
  const double before = xix * xix + xiy * xiy + xiz * xiz;
  const double xn = xix * nx + xiy * ny + xiz * nz;
  xix -= xn * nx;
  xiy -= xn * ny;
  xiz -= xn * nz;
  const double after = xix * xix + xiy * xiy + xiz * xiz;
  const double keep = after > 0.0 ? std::sqrt(before / (after > 0.0 ? after : 1.0)) : 1.0;
  xix = xix * keep + vtx * dt;
  xiy = xiy * keep + vty * dt;
  xiz = xiz * keep + vtz * dt;
  double ftx = -st * xix - gt * vtx, fty = -st * xiy - gt * vty, ftz = -st * xiz - gt * vtz;
  // Coulomb cap; the spring is rewound so that it alone carries the capped force
  const double ft2 = ftx * ftx + fty * fty + ftz * ftz;
  const double cap = law.friction() * (fn > 0.0 ? fn : 0.0);
  const bool slip = ft2 > cap * cap;
  const double s = slip ? cap / std::sqrt(slip ? ft2 : 1.0) : 1.0;
  ftx *= s;
  fty *= s;
  ftz *= s;
  xi_x = slip ? -(ftx + gt * vtx) * inv_st : xix;
  xi_y = slip ? -(fty + gt * vty) * inv_st : xiy;
  xi_z = slip ? -(ftz + gt * vtz) * inv_st : xiz;
  fx = fn * nx + ftx;
  fy = fn * ny + fty;
  fz = fn * nz + ftz;
  return fn;
}

/// contact_lane on Vec3s: what each law's force() returns.
template <class Law>
[[gnu::always_inline]] inline ContactResult contact_force(const Law& law, double delta, double rstar, const Vec3& n,
                                                          double vn, const Vec3& vt, double m_eff, double dt,
                                                          Vec3& xi) {
  double fx, fy, fz;
  const double fn = contact_lane(law, delta, rstar, std::sqrt(m_eff), n.x(), n.y(), n.z(), vn, vt.x(), vt.y(), vt.z(),
                                 dt, xi.x(), xi.y(), xi.z(), fx, fy, fz);
  return {Vec3(fx, fy, fz), fn};
}

}  // namespace hs::bonded

// Linear spring-dashpot contact with Coulomb friction (Cundall & Strack 1979).
//
//   F_n = k_n * delta - gamma_n * v_n                      (normal, along n, repulsive > 0)
//   xi  <- rotate(xi onto the tangent plane) + v_t * dt    (tangential spring history)
//   F_t = -k_t * xi - gamma_t * v_t,  |F_t| <= mu * max(F_n, 0)   (Coulomb cap; xi is
//         rewound so that the spring alone carries the capped force)
//   gamma = 2 * zeta * sqrt(m_eff * k),
//   zeta  = -ln(e) / sqrt(pi^2 + ln^2(e))                  (e: coefficient of restitution)
//
// Stiffness defaults to the paper's Eq. 1, k_n = k_t = pi*E*D/12.
// The normal force is not clipped at zero: contact ends when the overlap returns
// to zero, which is what makes the restitution coefficient and contact time exactly
//   e = exp(-pi*zeta/sqrt(1-zeta^2)),  t_c = pi / (omega_n*sqrt(1-zeta^2)),
//   omega_n = sqrt(k_n/m_eff).
// (The short tensile tail at the end of a damped contact is the price of that.)
//
// Sign conventions of the inputs (computed by the pair loop):
//   n     unit normal pointing from particle i to particle j (or from wall to particle)
//   vn    normal relative velocity of j w.r.t. i, positive when separating
//   vt    tangential relative velocity of j's contact point w.r.t. i's
// Output: force on j (the force on i is its negative).
#pragma once

#include "common/contact_model.h"
#include "common/types.h"

#include <algorithm>
#include <cmath>

namespace hs::bonded {

/// zeta from a coefficient of restitution e in (0, 1].
inline double damping_ratio_from_restitution(double e) {
  if (e >= 1.0) return 0.0;
  const double l = std::log(e);
  return -l / std::sqrt(kPi * kPi + l * l);
}

/// Restitution of a linear spring-dashpot with damping ratio zeta < 1.
inline double restitution_from_damping_ratio(double zeta) {
  return std::exp(-kPi * zeta / std::sqrt(1.0 - zeta * zeta));
}

struct LinearContactParams {
  double kn = 0.0;      ///< normal stiffness, N/m
  double kt = 0.0;      ///< tangential stiffness, N/m
  double zeta_n = 0.0;  ///< normal damping ratio
  double zeta_t = 0.0;  ///< tangential damping ratio
  double mu = 0.0;      ///< Coulomb friction coefficient
};

/// Projects the tangential history onto the current tangent plane, keeping its length
/// (the contact frame rotates with the pair).
inline void rotate_history(Vec3& xi, const Vec3& n) {
  const double before = xi.squaredNorm();
  if (before == 0.0) return;
  xi -= xi.dot(n) * n;
  const double after = xi.squaredNorm();
  if (after > 0.0) xi *= std::sqrt(before / after);
}

/// Coulomb cap shared by the contact laws: caps ft at mu*fn_limit and rewinds the
/// spring history so the elastic part alone carries the capped force.
inline void coulomb_cap(Vec3& ft, Vec3& xi, const Vec3& vt, double kt, double gamma_t,
                        double mu, double fn_limit) {
  const double ft2 = ft.squaredNorm();
  const double cap = mu * fn_limit;
  if (ft2 > cap * cap) {
    const double s = ft2 > 0.0 ? cap / std::sqrt(ft2) : 0.0;
    ft *= s;
    xi = kt > 0.0 ? Vec3(-(ft + gamma_t * vt) / kt) : Vec3::Zero();
  }
}

struct ContactResult {
  Vec3 force;     ///< on j, N
  double fn;      ///< signed normal force, N (repulsive > 0)
};

inline ContactResult linear_contact(const LinearContactParams& p, double delta, const Vec3& n,
                                    double vn, const Vec3& vt, double m_eff, double dt, Vec3& xi) {
  const double gn = 2.0 * p.zeta_n * std::sqrt(m_eff * p.kn);
  const double gt = 2.0 * p.zeta_t * std::sqrt(m_eff * p.kt);
  const double fn = p.kn * delta - gn * vn;
  rotate_history(xi, n);
  xi += vt * dt;
  Vec3 ft = -p.kt * xi - gt * vt;
  coulomb_cap(ft, xi, vt, p.kt, gt, p.mu, fn > 0.0 ? fn : 0.0);
  return {fn * n + ft, fn};
}

/// Elastic energy stored in a linear contact (for energy bookkeeping).
inline double linear_contact_energy(const LinearContactParams& p, double delta, const Vec3& xi) {
  return 0.5 * p.kn * delta * delta + 0.5 * p.kt * xi.squaredNorm();
}

/// Spring constants and damping ratio of a contact law for the engine's time-step check
/// (Engine::critical_time_step): the stiffest contact between the smallest particles.
struct ContactStiffness {
  double kn = 0.0;    ///< normal, N/m
  double kt = 0.0;    ///< tangential, N/m
  double zeta = 0.0;  ///< largest damping ratio (normal or tangential)
};

/// The linear law behind the dispatch point (contact_law.h; docs/engine.md, "Adding a contact law").
struct LinearLaw {
  static constexpr ContactModel kModel = ContactModel::LinearSpringDashpot;
  LinearContactParams p;

  /// Its parameters from an EngineDef (a template: engine.h includes this file).
  template <class Def>
  [[gnu::always_inline]] static LinearLaw from_def(const Def& d) {
    return {d.contact};
  }
  /// The same law against a surface with its own friction (walls, meshes, rigid blocks).
  [[gnu::always_inline]] LinearLaw with_friction(double mu) const {
    LinearLaw l = *this;
    l.p.mu = mu;
    return l;
  }
  [[gnu::always_inline]] ContactResult force(double delta, double /*r_star*/, const Vec3& n, double vn, const Vec3& vt, double m_eff,
                      double dt, Vec3& xi) const {
    return linear_contact(p, delta, n, vn, vt, m_eff, dt, xi);
  }
  [[gnu::always_inline]] double energy(double delta, double /*r_star*/, const Vec3& xi) const { return linear_contact_energy(p, delta, xi); }
  /// Constant springs: k_n, k_t and the larger damping ratio, whatever the particle size.
  ContactStiffness time_step_stiffness(double /*r_min*/) const {
    return {p.kn, p.kt, std::max(p.zeta_n, p.zeta_t)};
  }
  /// One stiffness that sizes other steps (the rigid step, HybridSystem): k_n.
  double reference_stiffness(double /*youngs_modulus*/, double /*diameter*/) const { return p.kn; }
};

}  // namespace hs::bonded

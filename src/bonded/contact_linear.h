// Linear spring-dashpot contact with Coulomb friction (Cundall & Strack 1979).
//
//   F_n = k_n * delta - gamma_n * v_n                      (normal, along n, repulsive > 0)
//   xi  <- rotate(xi onto the tangent plane) + v_t * dt    (tangential spring history)
//   F_t = -k_t * xi - gamma_t * v_t,  |F_t| <= mu * max(F_n, 0)   (Coulomb cap; xi is
//         rewound so that the spring alone carries the capped force)
//   gamma = 2 * zeta * sqrt(k) * sqrt(m_eff),
//   zeta  = -ln(e) / sqrt(pi^2 + ln^2(e))                  (e: coefficient of restitution)
//
// Stiffness defaults to the paper's Eq. 1, k_n = k_t = pi*E*D/12.
// The normal force is not clipped at zero: contact ends when the overlap returns
// to zero, which is what makes the restitution coefficient and contact time exactly
//   e = exp(-pi*zeta/sqrt(1-zeta^2)),  t_c = pi / (omega_n*sqrt(1-zeta^2)),
//   omega_n = sqrt(k_n/m_eff).
// (The short tensile tail at the end of a damped contact is the price of that.)
//
// The shared part (spring history, Coulomb cap) is contact_lane.h's, which also states the sign
// conventions; this file gives the law's springs and damping (LinearLaw::lane_springs).
#pragma once

#include "common/contact_model.h"
#include "contact_lane.h"
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
  double inv_kt = 0.0;  ///< 1 / k_t (0 for no tangential spring)
  double cn = 0.0;      ///< 2 zeta_n sqrt(k_n): gamma_n = cn sqrt(m_eff)
  double ct = 0.0;      ///< 2 zeta_t sqrt(k_t)

  static LinearLaw make(const LinearContactParams& p) {
    return {p, p.kt > 0.0 ? 1.0 / p.kt : 0.0, 2.0 * p.zeta_n * std::sqrt(p.kn), 2.0 * p.zeta_t * std::sqrt(p.kt)};
  }
  /// Its parameters from an EngineDef (a template: engine.h includes this file).
  template <class Def>
  static LinearLaw from_def(const Def& d) {
    return make(d.contact);
  }
  /// The same law against a surface with its own friction (walls, meshes, rigid blocks).
  LinearLaw with_friction(double mu) const {
    LinearLaw l = *this;
    l.p.mu = mu;
    return l;
  }
  double friction() const { return p.mu; }
  /// contact_lane's springs: f_el = k_n delta, S_t = k_t, gamma = c sqrt(m_eff).
  [[gnu::always_inline]] void lane_springs(double delta, double /*rstar*/, double smeff, double& fel, double& st,
                                           double& inv_st, double& gn, double& gt) const {
    fel = p.kn * delta;
    st = p.kt;
    inv_st = inv_kt;
    gn = cn * smeff;
    gt = ct * smeff;
  }
  ContactResult force(double delta, double r_star, const Vec3& n, double vn, const Vec3& vt, double m_eff, double dt,
                      Vec3& xi) const {
    return contact_force(*this, delta, r_star, n, vn, vt, m_eff, dt, xi);
  }
  double energy(double delta, double /*r_star*/, const Vec3& xi) const { return linear_contact_energy(p, delta, xi); }
  /// Constant springs: k_n, k_t and the larger damping ratio, whatever the particle size.
  ContactStiffness time_step_stiffness(double /*r_min*/) const {
    return {p.kn, p.kt, std::max(p.zeta_n, p.zeta_t)};
  }
  /// One stiffness that sizes other steps (the rigid step, HybridSystem): k_n.
  double reference_stiffness(double /*youngs_modulus*/, double /*diameter*/) const { return p.kn; }
};

/// The linear law's force for one contact (LinearLaw::force).
inline ContactResult linear_contact(const LinearContactParams& p, double delta, const Vec3& n, double vn,
                                    const Vec3& vt, double m_eff, double dt, Vec3& xi) {
  return LinearLaw::make(p).force(delta, 0.0, n, vn, vt, m_eff, dt, xi);
}

}  // namespace hs::bonded

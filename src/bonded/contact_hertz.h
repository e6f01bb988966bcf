// Hertz-Mindlin contact with Coulomb friction (no-slip Mindlin tangential stiffness),
// damping after Tsuji et al. (1992) in the form used by LIGGGHTS/LAMMPS:
//
//   E* = E / (2 (1 - nu^2)),  G* = E / (4 (2 - nu)(1 + nu))     (identical materials)
//   R* = r_i r_j / (r_i + r_j),  a = sqrt(R* delta)
//   S_n = 2 E* a,   S_t = 8 G* a
//   F_n = 4/3 E* sqrt(R*) delta^(3/2) - gamma_n v_n
//   gamma_n = -2 sqrt(5/6) beta sqrt(S_n) sqrt(m_eff),  gamma_t likewise with S_t,
//   beta = ln(e) / sqrt(ln^2(e) + pi^2)
//   xi <- rotate(xi) + v_t dt,  F_t = -S_t xi - gamma_t v_t,  |F_t| <= mu max(F_n, 0)
//
// The shared part (spring history, Coulomb cap) and the sign conventions are contact_lane.h's.
#pragma once

#include "common/ice_formulas.h"
#include "contact_linear.h"

namespace hs::bonded {

struct HertzContactParams {
  double e_star = 0.0;   ///< effective Young's modulus, Pa
  double g_star = 0.0;   ///< effective shear modulus, Pa
  double beta = 0.0;     ///< ln(e)/sqrt(ln^2 e + pi^2) (<= 0)
  double mu = 0.0;       ///< Coulomb friction

  static HertzContactParams from_material(double E, double nu, double restitution, double mu) {
    HertzContactParams p;
    p.e_star = E / (2.0 * (1.0 - nu * nu));
    p.g_star = E / (4.0 * (2.0 - nu) * (1.0 + nu));
    const double l = std::log(restitution >= 1.0 ? 1.0 : restitution);
    p.beta = l / std::sqrt(l * l + kPi * kPi);
    p.mu = mu;
    return p;
  }
};

/// Normal elastic energy of a Hertz contact: 8/15 E* sqrt(R*) delta^(5/2).
inline double hertz_contact_energy(const HertzContactParams& p, double delta, double r_star) {
  return (8.0 / 15.0) * p.e_star * std::sqrt(r_star) * std::pow(delta, 2.5);
}

/// The Hertz-Mindlin law behind the dispatch point (contact_law.h; docs/engine.md).
struct HertzLaw {
  static constexpr ContactModel kModel = ContactModel::HertzMindlin;
  HertzContactParams p;
  double reference_overlap = 0.02;  ///< overlap / radius at which the time-step check takes the stiffness
  double c = 0.0;                   ///< -2 sqrt(5/6) beta: gamma = c sqrt(S) sqrt(m_eff)

  static HertzLaw make(const HertzContactParams& p, double reference_overlap) {
    constexpr double two_sqrt_5_6 = 1.8257418583505538;
    return {p, reference_overlap, -two_sqrt_5_6 * p.beta};
  }
  template <class Def>
  static HertzLaw from_def(const Def& d) {
    return make(d.hertz, d.hertz_reference_overlap);
  }
  HertzLaw with_friction(double mu) const {
    HertzLaw l = *this;
    l.p.mu = mu;
    return l;
  }
  double friction() const { return p.mu; }
  /// contact_lane's springs: a = sqrt(R* delta), S_n = 2 E* a, S_t = 8 G* a,
  /// f_el = 4/3 E* a delta, gamma = c sqrt(S) sqrt(m_eff).
  [[gnu::always_inline]] void lane_springs(double delta, double rstar, double smeff, double& fel, double& st,
                                           double& inv_st, double& gn, double& gt) const {
    const double a = std::sqrt(rstar * (delta > 0.0 ? delta : 0.0));
    const double sn = 2.0 * p.e_star * a;
    st = 8.0 * p.g_star * a;
    inv_st = st > 0.0 ? 1.0 / (st > 0.0 ? st : 1.0) : 0.0;
    fel = (4.0 / 3.0) * p.e_star * a * delta;
    gn = c * std::sqrt(sn) * smeff;
    gt = c * std::sqrt(st) * smeff;
  }
  ContactResult force(double delta, double r_star, const Vec3& n, double vn, const Vec3& vt, double m_eff, double dt,
                      Vec3& xi) const {
    return contact_force(*this, delta, r_star, n, vn, vt, m_eff, dt, xi);
  }
  /// Normal (Hertz) plus tangential spring energy 1/2 S_t |xi|^2.
  double energy(double delta, double r_star, const Vec3& xi) const {
    const double st = 8.0 * p.g_star * std::sqrt(r_star * delta);
    return hertz_contact_energy(p, delta, r_star) + 0.5 * st * xi.squaredNorm();
  }
  /// S_n, S_t of two particles of the smallest radius at the reference overlap; the damping ratio
  /// gamma / (2 sqrt(S m_eff)) = sqrt(5/6) |beta| does not depend on the overlap.
  ContactStiffness time_step_stiffness(double r_min) const {
    const double rs = 0.5 * r_min;
    const double a = std::sqrt(rs * reference_overlap * r_min);
    return {2.0 * p.e_star * a, 8.0 * p.g_star * a, std::sqrt(5.0 / 6.0) * (-p.beta)};
  }
  /// The stiffness varies with the overlap: paper Eq. 1 (pi E D / 12) sizes other steps.
  double reference_stiffness(double youngs_modulus, double diameter) const {
    return eq1_contact_stiffness(youngs_modulus, diameter);
  }
};

}  // namespace hs::bonded

// Parallel bond (Potyondy & Cundall 2004), written in total (not incremental) form so
// that the elastic part derives from an energy: it conserves energy and is time-
// reversible when undamped, and its force/moment are checked against -dE/dx in tests.
//
// Reference state, fixed when the bond is made (in each particle's body frame):
//   r_i, r_j   lever arms from each centre to the bond centre (the contact point)
//   c          relative-orientation reference, c = q_j0^* q_i0
// Current kinematics (q: body->world):
//   a_i = q_i r_i,  a_j = q_j r_j,   d = x_j - x_i,  L = |d|,  n = d / L
//   u   = d + a_j - a_i                         (gap opening at the bond centre)
//   u_n = u.n,  u_s = u - u_n n                 (normal / shear parts)
//   W   = q_j c q_i^*  = exp(theta)             (relative rotation since bonding)
//   theta_n = theta.n n,  theta_s = theta - theta_n   (twist / bending parts)
// Energy (P&C stiffnesses: k_n = kn_bar A, k_s = ks_bar A, k_b = kn_bar I, k_t = ks_bar J)
//   E = 1/2 k_n u_n^2 + 1/2 k_s |u_s|^2 + 1/2 k_b |theta_s|^2 + 1/2 k_t |theta_n|^2
// Exact gradient (f_u = dE/du, g = dE/dtheta, P = I - n n^T):
//   F_j = -f_u - P[(k_n-k_s) u_n u + (k_t-k_b) theta_n theta] / L,  F_i = -F_j
//   T_i =  a_i x f_u + J_l^-1(theta) g,   T_j = -a_j x f_u - J_r^-1(theta) g
//   J_l^-1 = I - 1/2[theta]x + c2 [theta]x^2,  J_r^-1 = I + 1/2[theta]x + c2 [theta]x^2,
//   c2 = 1/phi^2 - (1 + cos phi)/(2 phi sin phi),  phi = |theta|
// (the SO(3) log-map Jacobians). Linear and angular momentum are conserved exactly
// because E is invariant under rigid translation and rotation of the pair.
// Damping (not from the energy): relative velocity and spin at the bond centre,
//   F_d = -(gamma_n v_n n + gamma_s v_s),  M_d = -(gamma_b w_s + gamma_t w_n)
// applied to j (and opposite to i) at the mid-point of the two bond-centre points, so
// it conserves angular momentum too.
// Stresses (P&C Eq. 8; bond radius R, area A = pi R^2, I = pi R^4/4, J = pi R^4/2):
//   sigma = k_n u_n / A + k_b |theta_s| R / I     (tension positive)
//   tau   = k_s |u_s| / A + k_t |theta_n| R / J
//   crush = -k_n u_n / A + k_b |theta_s| R / I    (largest compressive stress, compression positive)
// The bond breaks when sigma > sigma_c or tau > tau_c, or crush > sigma_cc (a compressive
// strength: none by default, as in P&C); its force is then removed.
#pragma once

#include "common/types.h"

#include <cmath>
#include <cstdint>

namespace hs::bonded {

struct ParallelBondParams {
  double kn = 0, ks = 0;        ///< N/m
  double kb = 0, kt = 0;        ///< N m/rad (bending, twisting)
  double gamma_n = 0, gamma_s = 0;  ///< N s/m
  double gamma_b = 0, gamma_t = 0;  ///< N m s/rad
  double radius = 0;            ///< bond radius R, m
  double sigma_c = INFINITY;    ///< tensile strength, Pa
  double tau_c = INFINITY;      ///< shear strength, Pa
  double sigma_cc = INFINITY;   ///< compressive strength, Pa (none: P&C bonds never fail in compression)
  // Stress per unit deformation, derived by finalize(): k_n/A, k_b R/I, k_s/A, k_t R/J.
  double sigma_per_stretch = 0, sigma_per_bend = 0, tau_per_slide = 0, tau_per_twist = 0;

  /// Derives the stress factors from the stiffnesses and radius; call after editing them.
  ParallelBondParams& finalize() {
    sigma_per_stretch = kn / area();
    sigma_per_bend = kb * radius / inertia();
    tau_per_slide = ks / area();
    tau_per_twist = kt * radius / polar();
    return *this;
  }

  double area() const { return kPi * radius * radius; }
  double inertia() const { return 0.25 * kPi * radius * radius * radius * radius; }
  double polar() const { return 2.0 * inertia(); }

  /// P&C parallel bond from the material: per-area stiffnesses chosen so that the
  /// bond's normal and shear stiffness equal k_n and k_s (paper Eq. 1: k = pi*E*D/12).
  /// Damping from a damping ratio zeta with the pair's reduced mass/inertia.
  static ParallelBondParams from_stiffness(double kn, double ks, double radius, double sigma_c,
                                           double tau_c, double zeta, double m_eff,
                                           double inertia_eff) {
    ParallelBondParams p;
    p.radius = radius;
    p.kn = kn;
    p.ks = ks;
    const double A = p.area();
    p.kb = kn / A * p.inertia();
    p.kt = ks / A * p.polar();
    p.gamma_n = 2.0 * zeta * std::sqrt(m_eff * p.kn);
    p.gamma_s = 2.0 * zeta * std::sqrt(m_eff * p.ks);
    p.gamma_b = 2.0 * zeta * std::sqrt(inertia_eff * p.kb);
    p.gamma_t = 2.0 * zeta * std::sqrt(inertia_eff * p.kt);
    p.sigma_c = sigma_c;
    p.tau_c = tau_c;
    p.finalize();
    return p;
  }
};

/// Reference state of one bond, set at creation.
struct BondRef {
  Vec3 ri;  ///< lever arm of i to the bond centre, i's body frame
  Vec3 rj;  ///< lever arm of j to the bond centre, j's body frame
  Quat c;   ///< q_j0^* q_i0

  /// Bond at the current configuration: centre at the mid-point of the gap between
  /// the two surfaces (contact point for touching spheres).
  static BondRef at_rest(const Vec3& xi, const Quat& qi, double ri_rad, const Vec3& xj,
                         const Quat& qj, double rj_rad) {
    const Vec3 d = xj - xi;
    const double L = d.norm();
    // Centre where the two spheres would touch, split in proportion to the radii.
    const Vec3 ci = d * (ri_rad / (ri_rad + rj_rad));
    BondRef b;
    b.ri = qi.conjugate() * ci;
    b.rj = qj.conjugate() * (ci - d);
    b.c = qj.conjugate() * qi;
    (void)L;
    return b;
  }
};

struct BondKinematics {
  const Vec3& xi; const Vec3& xj;
  const Quat& qi; const Quat& qj;
  const Vec3& vi; const Vec3& vj;
  const Vec3& wi; const Vec3& wj;
};

struct BondResult {
  Vec3 fj;       ///< force on j (force on i is -fj), N
  Vec3 ti, tj;   ///< torques on i and j, N m
  double sigma;  ///< max tensile stress, Pa
  double tau;    ///< max shear stress, Pa
  double crush;  ///< max compressive stress, Pa (compression positive)
  double energy; ///< elastic energy, J
};

/// How a bond fails, if it does: tension first, then shear, then compression.
enum class BondFailure : std::uint8_t { None, Tension, Shear, Compression };

/// `strength`: the bond's factor on the three strengths (Bond::strength; 1 exactly multiplies by 1).
inline BondFailure bond_failure(const ParallelBondParams& p, double sigma, double tau, double crush,
                                double strength = 1.0) {
  if (sigma > p.sigma_c * strength) return BondFailure::Tension;
  if (tau > p.tau_c * strength) return BondFailure::Shear;
  if (crush > p.sigma_cc * strength) return BondFailure::Compression;
  return BondFailure::None;
}

/// Below these the series of rotation_vector (t^2 = tan^2(phi/2)) and log_jacobian_c2 (phi^2) hold
/// to round-off; the bond kernel (bond_kernel.h) evaluates only the series and hands larger
/// rotations to parallel_bond.
inline constexpr double kRotationSeriesT2 = 1e-4;
inline constexpr double kLogJacobianSeriesPhi2 = 1e-3;

/// Rotation vector of a unit quaternion (log map), shortest arc.
inline Vec3 rotation_vector(const Quat& w_in) {
  Quat w = w_in;
  if (w.w() < 0.0) w.coeffs() = -w.coeffs();
  const Vec3 v = w.vec();
  const double s2 = v.squaredNorm();
  const double c = w.w();
  // Bonds break long before |theta| reaches 1e-2 rad in ice, so the series is the hot
  // path: atan(t)/t = 1 - t^2/3 + t^4/5 - t^6/7 with t = s/c, error < t^8/9 < 1e-17.
  const double ic = 1.0 / c;
  const double t2 = s2 * ic * ic;
  constexpr double k3 = 1.0 / 3.0, k5 = 1.0 / 5.0, k7 = 1.0 / 7.0;
  if (t2 < kRotationSeriesT2) return (2.0 * ic) * (1.0 - t2 * (k3 - t2 * (k5 - t2 * k7))) * v;
  const double s = std::sqrt(s2);
  return (2.0 * std::atan2(s, c) / s) * v;
}

/// c2 of the SO(3) log-map Jacobian by its series in phi^2 (any arithmetic type T):
/// c2 = 1/phi^2 - cot(phi/2)/(2 phi) = 1/12 + phi^2/720 + phi^4/30240 + phi^6/1209600 + O(phi^8),
/// next term phi^8/47900160: below phi^2 = 1e-3 its error is < 3e-19 relative.
template <class T>
inline T log_jacobian_c2_series(T phi2) {
  constexpr double k12 = 1.0 / 12.0, k720 = 1.0 / 720.0, k30240 = 1.0 / 30240.0, k1209600 = 1.0 / 1209600.0;
  return k12 + phi2 * (k720 + phi2 * (k30240 + phi2 * k1209600));
}

/// c2(phi) of the SO(3) log-map Jacobian from phi^2; series below phi = 0.0316 rad, where the
/// closed form loses digits to cancellation (1/phi^2 against a term as large).
inline double log_jacobian_c2(double phi2) {
  if (phi2 < kLogJacobianSeriesPhi2) return log_jacobian_c2_series(phi2);
  const double phi = std::sqrt(phi2);
  const double h = 0.5 * phi;
  return 1.0 / (phi * phi) - std::cos(h) / (2.0 * phi * std::sin(h));
}

inline BondResult parallel_bond(const ParallelBondParams& p, const BondRef& ref,
                                const BondKinematics& k) {
  BondResult r;
  const Vec3 ai = k.qi * ref.ri;
  const Vec3 aj = k.qj * ref.rj;
  const Vec3 d = k.xj - k.xi;
  const double invL = 1.0 / d.norm();
  const Vec3 n = d * invL;

  // --- translation ---
  const Vec3 u = d + aj - ai;
  const double un = u.dot(n);
  const Vec3 us = u - un * n;
  const Vec3 fu = p.kn * un * n + p.ks * us;

  // --- rotation ---
  const Quat W = k.qj * ref.c * k.qi.conjugate();
  const Vec3 th = rotation_vector(W);
  const double thn = th.dot(n);
  const Vec3 ths = th - thn * n;
  const Vec3 g = p.kb * th + (p.kt - p.kb) * thn * n;
  const double c2 = log_jacobian_c2(th.squaredNorm());
  const Vec3 txg = th.cross(g);
  const Vec3 txtxg = th.cross(txg);

  // n-dependence of the anisotropic terms: dE/dn = (kn-ks) un u + (kt-kb) thn th, projected.
  Vec3 dn = (p.kn - p.ks) * un * u + (p.kt - p.kb) * thn * th;
  dn -= dn.dot(n) * n;

  r.fj = -fu - dn * invL;
  r.ti = ai.cross(fu) + (g - 0.5 * txg + c2 * txtxg);
  r.tj = -aj.cross(fu) - (g + 0.5 * txg + c2 * txtxg);

  // --- damping, applied at the mid-point of the two bond-centre points ---
  if (p.gamma_n > 0.0 || p.gamma_s > 0.0 || p.gamma_b > 0.0 || p.gamma_t > 0.0) {
    const Vec3 vrel = (k.vj + k.wj.cross(aj)) - (k.vi + k.wi.cross(ai));
    const double vn = vrel.dot(n);
    const Vec3 fd = -(p.gamma_n * vn * n + p.gamma_s * (vrel - vn * n));
    const Vec3 mid_i = ai + 0.5 * u;  // mid-point relative to x_i
    const Vec3 mid_j = mid_i - d;     // same point relative to x_j
    const Vec3 wrel = k.wj - k.wi;
    const double wn = wrel.dot(n);
    const Vec3 md = -(p.gamma_t * wn * n + p.gamma_b * (wrel - wn * n));
    r.fj += fd;
    r.ti += mid_i.cross(-fd) - md;
    r.tj += mid_j.cross(fd) + md;
  }

  // sigma = k_n u_n / A + k_b |theta_s| R / I,  tau = k_s |u_s| / A + k_t |theta_n| R / J
  const double bend = p.sigma_per_bend * ths.norm();
  r.sigma = p.sigma_per_stretch * un + bend;
  r.crush = -p.sigma_per_stretch * un + bend;
  r.tau = p.tau_per_slide * us.norm() + p.tau_per_twist * std::abs(thn);
  r.energy = 0.5 * (p.kn * un * un + p.ks * us.squaredNorm() + p.kb * ths.squaredNorm() +
                    p.kt * thn * thn);
  return r;
}

}  // namespace hs::bonded

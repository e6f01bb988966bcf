// Validation of the bonded HCP ice lattice against analytical results
// (/work/shared/reference/validation.md, "Analytical checks for the particle model").
//
// Common set-up: ice D = 0.5 m, rho_i = 920 kg/m^3, Kn = Kt = pi E D / 12 (paper Eq. 1);
// particles on hcp_fill_box with the lattice-cell mass and buoyant volume
// (V_cell = D^3/sqrt(2)); every touching pair bonded with a parallel bond
// kn = ks = k, R = D/2 (ParallelBondParams::from_stiffness). The time step is the
// engine default (paper Eq. 2, alpha = 0.1), checked with check_time_step().
//
// Lattice elasticity used below (derived here, checked by test 1). With kn = ks = k a
// bond is an isotropic spring on the relative displacement u of the bond centre. Under
// a homogeneous strain eps with no particle rotation, u = D eps n for a bond along n;
// since sum_12 n = 0 and sum_12 n n^T = 4 I in HCP, every particle is in force and
// torque balance, so the affine field is the exact lattice response (no internal
// relaxation), also at free side faces of a bar (their missing neighbours are mirror
// images in z). The strain energy per cell is (k D^2 / 2) sum_6 |eps n|^2 =
// (k D^2) tr(eps^2), i.e. an isotropic solid with
//   lambda = 0,  mu = sqrt(2) k / D,  E_lat = 2 sqrt(2) k / D = (pi sqrt(2)/6) E = 0.7405 E,
//   nu_lat = 0.
// (validation.md's 1.70 k/d along c is for central springs only; the shear springs
// add stiffness and remove the Poisson effect.)
#include "fixtures.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

using namespace hs;
using namespace hs::bonded;

namespace {

constexpr double kRhoW = 1025.0;
constexpr double kG = 9.81;

/// Engine definition with the lattice bond of the paper (kn = ks = pi E D / 12).
EngineDef lattice_def(const test::Ice& ice, double sigma_c, double tau_c, double zeta) {
  EngineDef d = test::no_field_def(ice);
  const double m = ice.cell_mass(), I = 0.4 * m * 0.25 * ice.D * ice.D;
  d.bond[0] = ParallelBondParams::from_stiffness(ice.kn(), ice.kn(), 0.5 * ice.D, sigma_c, tau_c, zeta,
                                                 0.5 * m, 0.5 * I);
  return d;
}

/// Bulk Young's modulus of the kn = ks HCP lattice (see the header comment).
double lattice_modulus(const test::Ice& ice) { return 2.0 * std::sqrt(2.0) * ice.kn() / ice.D; }

/// Finite free-free Euler-Bernoulli beam of length L on a Winkler foundation kf (N/m^2),
/// flexural rigidity EI (N m^2), point load P (N, positive down) at x = a; returns the
/// deflection under the load. Cubic Hermite elements, consistent foundation matrix.
double beam_on_foundation(double EI, double kf, double L, double a, double P, int ne = 400) {
  const double l = L / ne;
  const int n = 2 * (ne + 1);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
  Eigen::Matrix4d ke, kfe;
  ke << 12, 6 * l, -12, 6 * l, 6 * l, 4 * l * l, -6 * l, 2 * l * l, -12, -6 * l, 12, -6 * l, 6 * l,
      2 * l * l, -6 * l, 4 * l * l;
  ke *= EI / (l * l * l);
  kfe << 156, 22 * l, 54, -13 * l, 22 * l, 4 * l * l, 13 * l, -3 * l * l, 54, 13 * l, 156, -22 * l,
      -13 * l, -3 * l * l, -22 * l, 4 * l * l;
  kfe *= kf * l / 420.0;
  for (int e = 0; e < ne; ++e) K.block<4, 4>(2 * e, 2 * e) += ke + kfe;
  auto shape = [&](double xi) {
    return Eigen::Vector4d(1 - 3 * xi * xi + 2 * xi * xi * xi, l * (xi - 2 * xi * xi + xi * xi * xi),
                           3 * xi * xi - 2 * xi * xi * xi, l * (-xi * xi + xi * xi * xi));
  };
  const int ea = std::min(ne - 1, static_cast<int>(a / l));
  const Eigen::Vector4d N = shape(a / l - ea);
  Eigen::VectorXd F = Eigen::VectorXd::Zero(n);
  F.segment<4>(2 * ea) = P * N;
  const Eigen::VectorXd w = K.ldlt().solve(F);
  return N.dot(w.segment<4>(2 * ea));
}

}  // namespace

// ---------------------------------------------------------------------------------
// 1. HCP bar in uniaxial tension along the c-axis: Young's modulus and strength.
// ---------------------------------------------------------------------------------
TEST(Validation, HcpBarTensionAlongCAxis) {
  test::Ice ice;  // full E = 1e9 Pa
  const double D = ice.D, c = hcp_layer_spacing(D), k = ice.kn();
  const int nl = 24;                       // layers: bar ~ 9.8 m = 19.6 D long
  const double sigma_c = 1e6, tau_c = 1e6;  // Pa
  // Bond damping (zeta 0.3) removes the start-up transient; its force is proportional to
  // the (constant) strain rate, so it drops out of the fitted slope.
  EngineDef d = lattice_def(ice, sigma_c, tau_c, 0.3);
  Engine e(d);
  // Cross-section ~1.5 m x 1.5 m (3 x 3 particles per layer).
  const auto centres = hcp_fill_box(Vec3(0.75, 0.75, 0.5 * nl * c), Pose{}, D);
  const double z0 = -0.5 * nl * c + 0.5 * c;
  std::vector<int> layer_of;  // by global id (ids are 0..N-1 in insertion order)
  std::vector<GlobalId> clamp, pull;
  for (const auto& x : centres) {
    const int L = static_cast<int>(std::lround((x.z() - z0) / c));
    auto p = test::sphere_at(ice, x, true);
    if (L == 0 || L == nl - 1) p.flags = kFlagFrozen;
    const GlobalId g = e.particles().gid[e.add_particle(p)];
    ASSERT_EQ(g, layer_of.size());
    layer_of.push_back(L);
    if (L == 0) clamp.push_back(g);
    if (L == nl - 1) pull.push_back(g);
  }
  e.bond_touching(0, e.particles().size(), BondKind::Lattice);
  e.check_time_step();
  // Bonds crossing the mid interface (all interfaces are alike: ABAB stacking).
  int nb_cross = 0;
  for (const auto& b : e.bonds()) {
    const int la = layer_of[b.gi], lb = layer_of[b.gj];
    if (std::min(la, lb) == nl / 2 - 1 && std::max(la, lb) == nl / 2) ++nb_cross;
  }
  const double n_per_layer = static_cast<double>(centres.size()) / nl;  // mean over A and B layers
  // Cross-section: the lattice volume per layer over the layer spacing.
  const double area = n_per_layer * hcp_cell_volume(D) / c;
  const double L0 = (nl - 1) * c;  // distance between the clamp and the pulled layer
  const double nz = std::sqrt(2.0 / 3.0);  // cos of the inter-layer bond angle to the c-axis
  // Affine prediction for this bar: each crossing bond carries k D eps nz along z, so
  // sigma = nb k D nz eps / area.
  const double E_affine = nb_cross * k * D * nz / area;
  // Strength: a crossing bond has u_n = D eps nz^2 and u_s = D eps nz sqrt(1 - nz^2), so
  // tau / sigma = sqrt(1/nz^2 - 1) = 0.707 < 1 = tau_c / sigma_c: tension governs. It
  // breaks at u_n = sigma_c A_b / k, when its force (k u, along z) is sigma_c A_b / nz.
  const double Ab = kPi * 0.25 * D * D;  // bond of radius D/2: pi (D/2)^2, by hand (not area())
  const double F_break = nb_cross * sigma_c * Ab / nz;
  const double eps_c = sigma_c * Ab / (k * D * nz * nz);

  // Quasi-static pull: the end layer moves at V (linear ramp over 0.05 s), reaching
  // eps_c after ~1 s, i.e. ~90 P-wave transits of the bar.
  const double T_break = 1.0, t_ramp = 0.05;
  const double V = eps_c * L0 / (T_break - 0.5 * t_ramp);
  auto mean_z = [&](const std::vector<GlobalId>& ids) {
    double s = 0;
    for (auto g : ids) s += e.particles().x[e.particles().local(g)].z();
    return s / ids.size();
  };
  auto sum_fz = [&](const std::vector<GlobalId>& ids) {
    double s = 0;
    for (auto g : ids) s += e.particles().f[e.particles().local(g)].z();
    return s;
  };
  const double gap0 = mean_z(pull) - mean_z(clamp);
  std::vector<double> eps_s, F_s;
  double F_peak = 0, F_first = -1, F_prev = 0, eps_peak = 0;
  while (e.time() < 3.0 * T_break) {
    const double vz = V * std::min(1.0, e.time() / t_ramp);
    for (auto g : pull) e.particles().v[e.particles().local(g)] = Vec3(0, 0, vz);
    e.step();
    // Tension: mean of the reactions at the clamp (pulled +z) and at the pulled end (-z).
    const double F = 0.5 * (sum_fz(clamp) - sum_fz(pull));
    const double eps = (mean_z(pull) - mean_z(clamp)) / gap0 - 1.0;
    if (F_first < 0 && e.stats().bonds_broken > 0) F_first = F_prev;
    if (F > F_peak) { F_peak = F; eps_peak = eps; }
    F_prev = F;
    if (e.step_count() % 10 == 0) { eps_s.push_back(eps); F_s.push_back(F); }
    if (e.stats().bonds_broken > 0 && F < 0.3 * F_peak) break;
  }
  // Young's modulus: least-squares slope of stress vs strain over [0.2, 0.6] eps_c.
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int ns = 0;
  for (std::size_t i = 0; i < eps_s.size(); ++i) {
    if (eps_s[i] < 0.2 * eps_c || eps_s[i] > 0.6 * eps_c) continue;
    const double y = F_s[i] / area;
    sx += eps_s[i]; sy += y; sxx += eps_s[i] * eps_s[i]; sxy += eps_s[i] * y; ++ns;
  }
  ASSERT_GT(ns, 20);
  const double E_meas = (ns * sxy - sx * sy) / (ns * sxx - sx * sx);
  std::printf("[bar] %zu particles, %.2f per layer, %d layers, %d bonds cross a layer, area %.4f m^2\n",
              centres.size(), n_per_layer, nl, nb_cross, area);
  std::printf("[bar] E_meas = %.4e Pa = %.4f E; affine bar %.4e (%.4f E); bulk lattice 2sqrt2 k/D = %.4f E; "
              "meas/affine = %.4f\n",
              E_meas, E_meas / ice.E, E_affine, E_affine / ice.E, lattice_modulus(ice) / ice.E, E_meas / E_affine);
  std::printf("[bar] failure: first rupture at %.4e N, peak %.4e N at strain %.3e; predicted %.4e N at %.3e "
              "(nb sigma_c A_b / cos); ratio first %.4f, peak %.4f; broken %llu (tension %llu, shear %llu)\n",
              F_first, F_peak, eps_peak, F_break, eps_c, F_first / F_break, F_peak / F_break,
              (unsigned long long)e.stats().bonds_broken, (unsigned long long)e.stats().bonds_broken_tension,
              (unsigned long long)e.stats().bonds_broken_shear);
  // The affine response is exact for this lattice; the dynamic lag of the quasi-static pull
  // (V / c_P ~ 5e-5 vs eps ~ 1e-3) is a constant offset that the fitted slope ignores.
  // Measured 5.4e-10 (limit 5e-9, was 2 %).
  EXPECT_NEAR(E_meas / E_affine, 1.0, 5e-9);
  // The bar's modulus is below the bulk lattice value only through the missing bonds of
  // its edge particles; E_lat / E = pi sqrt(2)/6 = 0.7405 in the bulk. A 3x3 section
  // keeps nb / (3 n_per_layer) in [0.6, 1].
  EXPECT_GT(E_meas / ice.E, 0.6 * lattice_modulus(ice) / ice.E);
  EXPECT_LT(E_meas / ice.E, 1.02 * lattice_modulus(ice) / ice.E);
  // Strength: first rupture and peak load against the bond-strength prediction. Measured both
  // 0.9988 (-1.2e-3: the load is sampled one step before the first rupture). Limit 1.2 %
  // (was 10 %), so a bond area 10 % off fails here too.
  ASSERT_GT(F_first, 0.0) << "the bar did not break";
  EXPECT_NEAR(F_first / F_break, 1.0, 0.012);
  EXPECT_NEAR(F_peak / F_break, 1.0, 0.012);
  EXPECT_GT(e.stats().bonds_broken_tension, 0u);
}

// ---------------------------------------------------------------------------------
// 2. Floating strip (beam on an elastic foundation) loaded at one free end.
// ---------------------------------------------------------------------------------
TEST(Validation, FloatingStripEndLoadMatchesHetenyi) {
  test::Ice ice;
  ice.E = 5e7;  // reduced E: L_c ~ 6 m, so a 36 m strip (~6 L_c) is cheap
  const double D = ice.D, c = hcp_layer_spacing(D), k = ice.kn();
  const int nl = 4;  // h = 4 c = 1.63 m, h/D = 3.27
  const double h = nl * c;
  const double Lx = 36.0;
  const double draft = flotation_draft(h, ice.rho, kRhoW);
  EngineDef d = lattice_def(ice, INFINITY, INFINITY, 0.3);
  d.gravity = Vec3(0, 0, -kG);
  d.water.enabled = true;
  d.water.level = 0.0;
  d.water.density = kRhoW;
  d.water.model = BuoyancyModel::Column;
  // Heave damping ratio zeta = c_lin / (2 sqrt(rho_w g rho_i h)) = 0.75 (box_water.h (5a); the
  // lattice's bottom face carries it, docs/engine.md "Water drag").
  d.water.linear_drag_per_area = 0.75 * 2.0 * std::sqrt(kRhoW * kG * ice.rho * h);
  Engine e(d);
  Pose pose;
  pose.position = Vec3(0, 0, 0.5 * h - draft);  // floating equilibrium of the column model
  // 8 rows across (width b = 8 sqrt(3)/2 D = 3.46 m). The B layers sit row/3 off the A
  // layers across the strip, which heels the strip slightly; a 4-row strip (nearly square
  // section, metacentric height ~0.09 m) heels ~5 deg and creeps for seconds, 8 rows
  // (GM ~0.6 m) keep the heel < 1 deg and the roll well damped.
  const auto centres = hcp_fill_box(Vec3(0.5 * Lx, 1.78, 0.5 * h), pose, D);
  const double row = 0.5 * std::sqrt(3.0) * D;
  std::map<std::pair<long, long>, std::size_t> first_in_row;  // (layer, row) -> site
  double xmin = INFINITY, xmax = -INFINITY;
  for (std::size_t s = 0; s < centres.size(); ++s) {
    const auto& x = centres[s];
    e.add_particle(test::sphere_at(ice, x, true));
    xmin = std::min(xmin, x.x());
    xmax = std::max(xmax, x.x());
    const std::pair<long, long> key(std::lround(x.z() / c * 2.0), std::lround(x.y() / row * 3.0));
    auto it = first_in_row.find(key);
    if (it == first_in_row.end() || centres[it->second].x() > x.x()) first_in_row[key] = s;
  }
  e.bond_touching(0, e.particles().size(), BondKind::Lattice);
  e.check_time_step();
  std::vector<GlobalId> loaded;  // the end cross-section: first particle of each row of each layer
  double x_load = 0;
  for (const auto& [key, s] : first_in_row) {
    loaded.push_back(s);  // gid == insertion index
    x_load += centres[s].x();
  }
  x_load /= loaded.size();
  const double nrows = static_cast<double>(loaded.size()) / nl;  // mean over A and B layers
  // Waterline layer: centres at z_top - c/2; counted against the plane halfway to the next layer
  // (z_top - c), not against their own height, where rounding decided (a build without FMA
  // counted none of them, and the strip's foundation stiffness came out 0).
  std::size_t n_top = 0;
  for (const auto& x : centres) n_top += x.z() > pose.position.z() + 0.5 * h - c;

  // ---- lattice flexural rigidity and foundation, from the actual bonds (central part) ----
  // Pure bending eps_xx = -kappa (z - z0) with particles rotating with the section: a bond
  // along n stores (k D^2 / 2) kappa^2 n_x^2 (z_b - z0)^2 (stretch/shear springs) plus
  // (k D^4 / 32) kappa^2 n_x^2 (1 + n_y^2) (bending and twisting springs, kb = k D^2/16,
  // kt = k D^2/8, relative rotation kappa D n_x about y). Affine, hence an upper bound.
  const double xc_lo = xmin + 3 * D, xc_hi = xmax - 3 * D;
  double sw = 0, swz = 0, swzz = 0, rot = 0;
  for (const auto& b : e.bonds()) {
    const Vec3 xa = centres[b.gi], xb = centres[b.gj];
    const Vec3 mid = 0.5 * (xa + xb);
    if (mid.x() < xc_lo || mid.x() > xc_hi) continue;
    const Vec3 n = (xb - xa).normalized();
    const double w = k * D * D * n.x() * n.x();
    sw += w; swz += w * mid.z(); swzz += w * mid.z() * mid.z();
    rot += k * std::pow(D, 4) / 16.0 * n.x() * n.x() * (1.0 + n.y() * n.y());
  }
  const double EI_axial = (swzz - swz * swz / sw) / (xc_hi - xc_lo);
  const double EI_lat = EI_axial + rot / (xc_hi - xc_lo);
  // Column buoyancy: each waterline particle is a spring rho_w g V_cell / c; spread over
  // the strip's length (end centres + D/2) that is a foundation kf = rho_w g b per unit
  // length, b the strip's effective width (~ rows * row).
  const double L_beam = xmax - xmin + 0.5 * D;
  const double kf = kRhoW * kG * hcp_cell_volume(D) / c * n_top / L_beam;
  const double b = kf / (kRhoW * kG);
  // Continuum: E_eff = 2 sqrt(2) k / D (bulk lattice, test 1), nu_lat = 0, h = n_layers c.
  const double E_eff = lattice_modulus(ice);
  const double EI_cont = E_eff * b * h * h * h / 12.0;
  const double beta = std::pow(kf / (4.0 * EI_cont), 0.25);
  const double Lc = 1.0 / (std::sqrt(2.0) * beta);

  // ---- settle unloaded, then ramp the end load on ----
  auto mean_z = [&](const std::vector<GlobalId>& ids) {
    double s = 0;
    for (auto g : ids) s += e.particles().x[e.particles().local(g)].z();
    return s / ids.size();
  };
  const double w_target = 0.04;  // m, well inside the freeboard (0.167 m): linear foundation
  const double P = w_target * kf / (2.0 * beta);  // N, total, downwards
  const double t_settle = 2.5, t_ramp = 2.5, t_end = 8.0;
  e.run(static_cast<std::uint64_t>(t_settle / e.dt()));
  const double z_ref = mean_z(loaded);
  const double t0 = e.time();
  // External load: the engine has no external-force input, so the load is applied as
  // the impulse P_i dt per step after each step (same momentum, same static equilibrium).
  e.on_step = [&](const Engine& en) {
    const double ramp = std::min(1.0, (en.time() - t0) / t_ramp);
    auto& ps = e.particles();
    for (auto g : loaded) {
      const auto i = ps.local(g);
      ps.v[i].z() -= ramp * P / loaded.size() * en.dt() * ps.inv_mass[i];
    }
  };
  // Run to t_end, sampling the end deflection each second (static by ~4 s after the ramp).
  std::vector<double> w_hist;
  while (e.time() < t_end) {
    e.run(static_cast<std::uint64_t>(1.0 / e.dt()));
    w_hist.push_back(z_ref - mean_z(loaded));
  }
  e.on_step = nullptr;
  const double w_meas = z_ref - mean_z(loaded);
  const double w_semi = 2.0 * P * beta / kf;
  const double a = x_load - (xmin - 0.25 * D);  // load inside the foundation's end
  const double w_fem_lat = beam_on_foundation(EI_lat, kf, L_beam, a, P);
  const double w_fem_cont = beam_on_foundation(EI_cont, kf, L_beam, a, P);
  std::printf("[strip] %zu particles, %d layers, h = %.3f m, %.1f rows (b = %.3f m), length %.2f m, %zu loaded, "
              "%zu at the waterline\n", centres.size(), nl, h, nrows, b, L_beam, loaded.size(), n_top);
  std::printf("[strip] E = %.3g Pa, E_eff = 2sqrt2 k/D = %.4g Pa, EI_cont = %.4e, EI_lattice = %.4e "
              "(axial %.4e) N m^2 (ratio %.3f), L_c = %.3f m, beta = %.4f 1/m\n",
              ice.E, E_eff, EI_cont, EI_lat, EI_axial, EI_lat / EI_cont, Lc, beta);
  std::printf("[strip] P = %.1f N: w_meas = %.5f m; semi-infinite 2 P beta/k = %.5f (ratio %.4f); "
              "finite beam, load at %.3f m: continuum %.5f (ratio %.4f), lattice EI %.5f (ratio %.4f)\n",
              P, w_meas, w_semi, w_meas / w_semi, a, w_fem_cont, w_meas / w_fem_cont, w_fem_lat,
              w_meas / w_fem_lat);
  std::printf("[strip] end deflection at 1 s intervals after loading began:");
  for (double w : w_hist) std::printf(" %.5f", w);
  std::printf("\n");
  // Static: the last two 1-s samples agree (heave damping ratio ~0.75); measured 1.6e-4
  // (limit 2e-3, was 5e-3). With the water's face drag (c_lin per m^2 on the bottom face, for
  // the same damping ratio, instead of 350 N s/m per particle) the samples agree to < 1e-4
  // (0.03944, 0.03944 m; before 0.03951, 0.03951 m), w / w_semi 0.9860 (0.9877), w / w_fem_lat
  // 1.0050 (1.0066).
  ASSERT_GE(w_hist.size(), 2u);
  EXPECT_NEAR(w_hist[w_hist.size() - 2] / w_meas, 1.0, 2e-3) << "not settled";
  // Brief's check: semi-infinite Hetenyi beam with the continuum E_eff, within 15 %: the
  // formula ignores the lattice's discreteness (4 layers: EI_lattice/EI_cont = 0.85 -> w
  // up ~4 %), the foundation beyond the load (the loaded centres sit ~D/4 inside the
  // strip's end -> w down ~5 %) and the finite length (~6 L_c, < 1 %).
  EXPECT_NEAR(w_meas / w_semi, 1.0, 0.15);
  // Sharper: the finite free-free beam with the lattice's own EI (from its bonds) and the
  // load where it is applied, within 5 %: the affine EI is an upper bound (non-affine
  // relaxation, transverse shear ~ (h/L_c)^2 soften the lattice a few %) and the
  // foundation's end is known to ~D/4.
  EXPECT_NEAR(w_meas / w_fem_lat, 1.0, 0.05);
}

// ---------------------------------------------------------------------------------
// 3. Floating bonded slab: freeboard and heave period.
// ---------------------------------------------------------------------------------
namespace {

struct Slab {
  Engine e;
  std::vector<GlobalId> top;
  double h;
};

/// A 4.5 m x 4.5 m bonded slab of nl layers whose bottom face (bottom of the buoyancy columns)
/// starts at z_bottom; water at z = 0.
void build_slab(Engine& e, const test::Ice& ice, int nl, double z_bottom, std::vector<GlobalId>& top) {
  const double c = hcp_layer_spacing(ice.D);
  Pose pose;
  pose.position = Vec3(0, 0, z_bottom + 0.5 * nl * c);
  auto centres = hcp_fill_box(Vec3(2.25, 2.25, 0.5 * nl * c), pose, ice.D);
  // A box cut from HCP generally holds different numbers of particles in its A and B
  // layers (the B layers are shifted by (D/2, row/3)); a solid slab has the same area in
  // every layer, so trim every layer to the smallest count, dropping particles from the
  // x edges. (Otherwise the partly submerged top layer must make up for the others'
  // count and the freeboard is off by a few %.)
  hcp_equalize_layers(centres, pose, ice.D);
  const double z_top = z_bottom + (nl - 0.5) * c;
  for (const auto& x : centres) {
    const auto i = e.add_particle(test::sphere_at(ice, x, true));
    if (std::abs(x.z() - z_top) < 0.1 * c) top.push_back(e.particles().gid[i]);
  }
  e.bond_touching(0, e.particles().size(), BondKind::Lattice);
  e.check_time_step();
}

/// zeta: heave damping ratio of a slab of thickness h, c_lin = 2 zeta sqrt(rho_w g rho_i h)
/// (box_water.h (5a): the linear drag on the bottom face; docs/engine.md "Water drag").
EngineDef floating_def(const test::Ice& ice, double zeta, double h) {
  EngineDef d = lattice_def(ice, INFINITY, INFINITY, 0.1);
  d.gravity = Vec3(0, 0, -kG);
  d.water.enabled = true;
  d.water.level = 0.0;
  d.water.density = kRhoW;
  d.water.model = BuoyancyModel::Column;
  d.water.linear_drag_per_area = 2.0 * zeta * std::sqrt(kRhoW * kG * ice.rho * h);
  return d;
}

double mean_z(const Engine& e, const std::vector<GlobalId>* ids = nullptr) {
  const auto& p = e.particles();
  double s = 0;
  if (ids) {
    for (auto g : *ids) s += p.x[p.local(g)].z();
    return s / ids->size();
  }
  for (std::size_t i = 0; i < p.owned(); ++i) s += p.x[i].z();
  return s / p.owned();
}

}  // namespace

TEST(Validation, FloatingSlabFreeboardAndHeavePeriod) {
  test::Ice ice;
  ice.E = 2e7;  // reduced E (dt 7x larger); the slab still moves as a rigid body
  const int nl = 4;
  const double c = hcp_layer_spacing(ice.D), h = nl * c;
  const double draft = flotation_draft(h, ice.rho, kRhoW);
  const double freeboard_th = flotation_freeboard(h, ice.rho, kRhoW);
  const double T_th = 2.0 * kPi * std::sqrt(ice.rho * h / (kRhoW * kG));

  // (a) Freeboard: released 0.1 m too high, heave damped by linear drag, settled.
  double freeboard = 0;
  {
    Engine e(floating_def(ice, 0.75, h));
    std::vector<GlobalId> top;
    build_slab(e, ice, nl, -draft + 0.1, top);
    e.run(static_cast<std::uint64_t>(8.0 / e.dt()));
    freeboard = mean_z(e, &top) + 0.5 * c;  // top of the top layer's buoyancy column
    std::printf("[slab] %zu particles, h = %.4f m: freeboard %.5f m vs h(1 - rho_i/rho_w) = %.5f m (ratio %.5f)\n",
                e.particles().size(), h, freeboard, freeboard_th, freeboard / freeboard_th);
  }
  // The column model makes the slab a solid column of height h; what is left is the
  // lattice's compression under its weight and residual motion. Measured 1.2e-7 (limit
  // 1.5e-6, was 2 %).
  EXPECT_NEAR(freeboard / freeboard_th, 1.0, 1.5e-6);

  // (b) Heave: released 0.05 m below equilibrium, no drag (bond damping acts only on
  // relative motion, so it does not damp the rigid heave).
  {
    Engine e(floating_def(ice, 0.0, h));
    std::vector<GlobalId> top;
    build_slab(e, ice, nl, -draft - 0.05, top);
    const double z_eq = mean_z(e) + 0.05;
    std::vector<double> up;  // upward crossings of the equilibrium, linear interpolation
    double zp = mean_z(e) - z_eq, tp = 0;
    while (e.time() < 4.5 * T_th) {
      e.step();
      const double z = mean_z(e) - z_eq;
      if (zp < 0 && z >= 0) up.push_back(tp + (e.time() - tp) * (-zp) / (z - zp));
      zp = z;
      tp = e.time();
    }
    ASSERT_GE(up.size(), 3u);
    const double T = (up.back() - up.front()) / (up.size() - 1);
    std::printf("[slab] heave period %.5f s (%zu cycles) vs 2 pi sqrt(rho_i h/(rho_w g)) = %.5f s (ratio %.5f)\n",
                T, up.size() - 1, T_th, T / T_th);
    // Exact for a uniform column slab. Here heave couples weakly to roll/pitch because the
    // B layers (the waterline layer) sit (D/2, row/3) off the A layers, so the waterplane
    // centroid is off the centre of mass: measured -1.2 % at 3 m square, -0.6 % at 4.5 m.
    // The lattice's own modes are >100x faster than heave and dt/T ~ 1e-4. Bound: 5 %.
    EXPECT_NEAR(T / T_th, 1.0, 0.05);
  }
}

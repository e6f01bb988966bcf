// ISO 19906 analytical ice loads on an upward-breaking cone: the upper-bound estimates that
// hybridsim prints next to the DEM result for the same ice (docs/iso19906.md).
//
// Level ice / consolidated layer on a cone: Croasdale & Cammaert (1994), as adopted by
// ISO 19906 (Annex A; clause not checked) and coded in OpenFAST IceFloe (IceFlexISO.f90).
// Angles in radians below; a = cone angle from horizontal, th = rubble slope angle,
// phi = rubble friction angle.
//   xi  = (sin a + mu cos a) / (cos a - mu sin a)
//   L_c = [E h^3 / (12 rho_w g (1 - nu^2))]^(1/4)                      characteristic length
//   l   = w + pi^2 L_c / 4                                              breaking circumference
//   H_B = 0.68 xi sigma_f (rho_w g h^5 / E)^(1/4) l                     breaking the sheet
//   H_P = w h_r^2 mu_i rho_i g (1-e) (1 - tan th/tan a)^2 / (2 tan th)  pushing through the pile
//   P   = 1/2 mu_i (mu_i+mu) rho_i g (1-e) h_r^2 sin a (cot th - cot a)(1 - tan th/tan a)
//       + 1/2 (mu_i+mu) rho_i g (1-e) h_r^2 cos a cot a (1 - tan th/tan a)
//       + h_r h rho_i g (sin a + mu cos a) / sin a                      (force per width)
//   H_R = w P / (cos a - mu sin a)                                      pushing blocks up the cone
//   H_L = xi w h_r (1 - tan th/tan a)
//         [1/2 h_r rho_i g (1-e)(cot th - cot a + tan phi (1 - tan th/tan a)) + c]
//                                                                       lifting the rubble
//   H_T = 1.5 w h^2 rho_i g cos a / (sin a - mu cos a)                  turning blocks at the top
//   F_H = (H_B + H_P + H_R + H_L + H_T) / (1 - H_B / (sigma_f l h))     total horizontal load
// Keel: Dolgopolov et al. (1975) plug failure, as used by ISO 19906, with w_k the width of
// the structure the keel meets (keel_width; 0 = the waterline diameter w):
//   F_K = mu_phi h_k w_k (h_k mu_phi gamma_e / 2 + 2 c)(1 + h_k / (6 w_k)),
//   mu_phi = tan(45 deg + phi/2),  gamma_e = (1 - e_k)(rho_w - rho_i) g;  F_K = 0 when h_k = 0,
// e_k the keel's porosity (keel_porosity; ISO has one porosity, e, for the pile and the keel: a
// JSON input without keel_porosity takes rubble_porosity).
// Ridge load (ISO): consolidated layer as level ice of the layer's thickness h, plus the keel:
//   F_total = F_H + F_K.
// These are upper bounds: on the Confederation Bridge piers ISO estimates exceed measured
// event peaks by about 1.6x on average (Croasdale et al. 2016).
//
// Validity (checked, InputError naming the JSON key): positive h, w, sigma_f, E, rho_i, g;
// rho_i < rho_w; 0 <= nu < 0.5; 0 < a < 90 deg; 0 < th < a; 0 <= phi < 90 deg; porosity in
// [0, 1); non-negative mu, mu_i, h_r, c, h_k, w_k; cos a - mu sin a > 0 (otherwise the cone is
// self-locking: the ice cannot slide up); sin a - mu cos a > 0 (otherwise blocks at the top
// cannot slide back down and H_T is undefined); 1 - H_B/(sigma_f l h) > 0.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace hs::analysis {

/// Ice, water, cone and rubble for the ISO 19906 estimate. SI units; JSON keys = field names.
/// Defaults: the Confederation Bridge pier of the reference DEM paper (0.6 m level ice,
/// 14 m waterline diameter, 52 deg cone), no keel.
struct IsoInputs {
  double thickness = 0.6;                  ///< h, level ice (or consolidated layer) thickness, m
  double waterline_diameter = 14.0;        ///< w, cone diameter at the waterline, m
  double flexural_strength = 0.5e6;        ///< sigma_f, Pa
  double youngs_modulus = 6.9e9;           ///< E, Pa (6.9 GPa gives L_c = 10.8 m for 0.6 m ice)
  double poisson_ratio = 0.3;              ///< nu, -
  double cone_angle_deg = 52.0;            ///< a, cone surface angle from horizontal, deg
  double friction_ice_structure = 0.1;     ///< mu, ice-cone friction coefficient, -
  double friction_ice_ice = 0.1;           ///< mu_i, ice-ice (rubble) friction coefficient, -
  double ice_density = 910.0;              ///< rho_i, kg/m^3
  double water_density = 1025.0;           ///< rho_w, kg/m^3
  double gravity = 9.81;                   ///< g, m/s^2
  double rubble_height = 5.0;              ///< h_r, height of the rubble pile on the cone, m
  double rubble_porosity = 0.3;            ///< e, rubble pile porosity, - in [0, 1)
  double rubble_cohesion = 3.0e3;          ///< c, rubble (and keel) cohesion, Pa
  double rubble_slope_deg = 40.0;          ///< th, rubble pile slope from horizontal, deg (< a)
  double rubble_friction_angle_deg = 30.0; ///< phi, rubble (and keel) internal friction angle, deg
  double keel_depth = 0.0;                 ///< h_k, keel depth below the consolidated layer, m
  double keel_width = 0.0;                 ///< w_k, structure width the keel meets, m; 0 = waterline_diameter
  double keel_porosity = 0.3;              ///< e_k, keel porosity, - in [0, 1) (JSON: rubble_porosity when not given)
};

/// The load components (N) and the derived quantities of the estimate.
struct IsoResult {
  double H_B = 0.0;  ///< breaking the ice sheet, N
  double H_P = 0.0;  ///< pushing the sheet through the rubble pile, N
  double H_R = 0.0;  ///< pushing the ice blocks up the cone, N
  double H_L = 0.0;  ///< lifting the rubble on top of the sheet, N
  double H_T = 0.0;  ///< turning the blocks at the top of the cone, N
  double F_H = 0.0;  ///< total horizontal level-ice load (Croasdale & Cammaert), N
  double F_K = 0.0;  ///< keel plug-failure load (Dolgopolov), N
  double F_total = 0.0;  ///< F_H + F_K, ISO ridge load, N
  double xi = 0.0;   ///< (sin a + mu cos a)/(cos a - mu sin a), -
  double L_c = 0.0;  ///< characteristic length of the floating sheet, m
  double l = 0.0;    ///< w + pi^2 L_c / 4, m
  double P = 0.0;    ///< ride-up force per unit width, N/m
};

/// The JSON keys of IsoInputs, in declaration order.
const std::vector<std::string>& iso_input_keys();

/// The SI unit of an input ("m", "Pa", "deg", "kg/m^3", "m/s^2"; "" for a dimensionless one);
/// std::out_of_range for a key that is not one of iso_input_keys().
std::string iso_input_unit(const std::string& key);

/// Throws hs::InputError naming `base_path + "/<key>"` if the inputs are outside the
/// validity range above.
void validate_iso_inputs(const IsoInputs& in, const std::string& base_path = "");

/// The Croasdale & Cammaert level-ice load and Dolgopolov keel load. Validates first.
IsoResult compute_iso(const IsoInputs& in);

/// The simulated peak over the ISO load it is judged against: peak / F_total (= F_H + F_K, the
/// ridge load; F_H alone when there is no keel, F_K = 0); 0 when F_total is not positive.
/// Every DEM/ISO ratio a run reports uses it, so a keel's term is never left out.
double dem_over_iso(double dem_peak, const IsoResult& r);

/// Reads a plain JSON object whose keys are the IsoInputs field names (numbers, SI units);
/// missing keys keep their defaults. Unknown keys (with a did-you-mean hint), non-numbers and
/// invalid values are hs::InputError naming `base_path + "/<key>"`. `base_path` is where the
/// object sits in a larger document ("" for a file that is just this object).
IsoInputs iso_inputs_from_json(const nlohmann::json& j, const std::string& base_path = "");

/// All inputs as a JSON object (iso_inputs_from_json(iso_inputs_to_json(x)) == x).
nlohmann::json iso_inputs_to_json(const IsoInputs& in);

/// {"H_B", "H_P", "H_R", "H_L", "H_T", "F_H", "F_K", "F_total" (N), "xi" (-), "L_c", "l" (m),
///  "P" (N/m)}.
nlohmann::json iso_to_json(const IsoResult& r);

}  // namespace hs::analysis

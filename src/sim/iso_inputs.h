// The ISO 19906 inputs of a run, each with where it came from (docs/iso19906.md, "Inputs of a
// run"). One function, assemble_iso_inputs, decides every input; /analysis/iso records the
// value, unit and source of each (docs/output.md).
//
// Sources:
//   scene       given in the scene file (or derived from what it gives: the pier geometry)
//   measured    measured in this run: the built lattice's mean thickness, the pile height
//   default     the scene does not give it; hybridsim's default (docs/scene.md)
//   ridge_file  the scene's ridge file (/blocks/ridge_file): keel depth, porosity
//   calibrated  the calibrated lattice's value (issue 13 items 1-2: E, nu, flexural strength)
// Precedence:
//   thickness          measured mean thickness of the built lattice (consolidated layer if
//                      any) > nominal scene thickness (`hybridsim iso` on a scene, no lattice)
//   youngs_modulus,    calibrated > material.* (scene/default)
//   poisson_ratio
//   flexural_strength  calibrated > material.flexural_strength > analysis.flexural_strength
//                      (scene/default)
//   rubble_height      analysis.rubble_height (scene) > the ISO-consistent pile height at the
//                      load peak (measured: PileAtLoadPeak) > the run's peak of
//                      /series/pile_height_mean (measured) > analysis default
//   rubble_slope_deg   analysis.rubble_slope_deg (scene) > the pile's slope at the load peak when
//                      in (0, cone angle) (measured) > 0.8 x cone angle (assumed, default)
//   rubble_porosity    analysis.rubble_porosity (scene) > the pile's porosity at the load peak
//                      (measured) > the ridge file's keel porosity > default
//   keel_porosity      analysis.rubble_porosity (scene) > the ridge file's keel porosity > default
//   keel_depth         analysis.keel_depth (scene) > ridge file: its keel depth below the
//                      waterline minus the depth of its consolidated layer's underside > 0 (default)
//   keel_width         the load-weighted width of the pier over the keel's depth range
//                      (keel_width_on_pier); source that of the pier geometry
//   the rest           the scene (pier, densities, friction, |gravity|) or the defaults.
#pragma once

#include "sim/calibrated_ice.h"
#include "sim/metrics.h"
#include "analysis/iso19906.h"
#include "bonded/particle_store.h"
#include "mesh/pier.h"
#include "scene/scene.h"

#include <optional>
#include <string>
#include <vector>

namespace hs::sim {

/// Where an ISO input came from; to_string gives the name written to /analysis/iso.
enum class IsoSource { Scene, Measured, Default, RidgeFile, Calibrated };
const char* to_string(IsoSource s);

/// One input of the estimate as used.
struct IsoInputRecord {
  std::string key;     ///< IsoInputs field name (analysis::iso_input_keys())
  double value = 0.0;
  std::string unit;    ///< "m", "Pa", "deg", "" (dimensionless), ...
  IsoSource source = IsoSource::Default;
  std::string note;    ///< how it was obtained, for people (may be empty)
  /// The source in a few words for the run summary and /analysis/iso/inputs/<key> "origin":
  /// "scene", "measured at t = 28.1 to 29.1 s (load peak)", "assumed 0.8 x cone angle", ...
  std::string origin;
};

/// What a ridge file says about its keel (sim::BlockSetup::ridge).
struct RidgeKeel {
  std::string path;                 ///< the ridge file, as resolved
  double keel_depth = 0.0;          ///< achieved keel depth below the waterline, m (RidgeStats)
  double layer_bottom_depth = 0.0;  ///< depth of the consolidated layer's underside below the waterline, m
  double porosity = 0.0;            ///< keel porosity (RidgeStats::keel_porosity)
};

/// What the run measured (each absent when not measured).
struct IsoMeasured {
  std::optional<double> thickness;      ///< mean thickness of the built lattice, m
  std::optional<double> rubble_height;  ///< the run's peak of /series/pile_height_mean, m
  /// The pile at the load peak (h_r, slope, porosity; NaN members: not measured).
  std::optional<PileAtLoadPeak> at_peak;
  std::optional<RidgeKeel> ridge;
  std::optional<CalibratedIce> calibrated;  ///< the lattice's E, nu, flexural strength ("calibrated" model)
  /// m below the waterline: the ridge file's keel counts down to this depth only, the ISO load
  /// "frozen" at that keel depth (the paper's Fig. 7 freezes it at the cone base, 4 m: the keel
  /// below meets the shaft). Absent: the whole keel.
  std::optional<double> keel_depth_limit;
};

/// Depth of the pier's cone base (its widest section) below the waterline, m: where the paper's
/// "frozen" ISO estimate stops the keel (IsoMeasured::keel_depth_limit).
double cone_base_depth(const scene::Scene& s);

struct IsoAssembly {
  analysis::IsoInputs in;
  std::vector<IsoInputRecord> records;  ///< one per analysis::iso_input_keys(), in that order
  /// The record of `key`; std::out_of_range if there is none.
  const IsoInputRecord& record(const std::string& key) const;
};

/// The inputs of the estimate for the scene's ice and pier and what the run measured.
/// InputError at /structure when the scene has no parametric pier. Does not validate the
/// inputs (analysis::compute_iso does).
IsoAssembly assemble_iso_inputs(const scene::Scene& s, const IsoMeasured& m);

/// Mean thickness of the built lattice where ISO breaks it (the consolidated layer's band if
/// the scene has one, else the whole sheet), m: the ice volume per unit area,
///   layers x (mean buoyant volume per particle) / (D^2 sqrt(3)/2),
/// with `layers` the number of distinct particle-centre heights (HCP layers c apart) among the
/// particles in that region and D^2 sqrt(3)/2 the area per particle in an HCP layer. For
/// particles carrying the HCP cell volume D^3/sqrt(2) this is layers x c, c = D sqrt(2/3).
/// 0 when there are no particles there. Call on the sheet as built (all particles present).
double lattice_mean_thickness(const bonded::ParticleStore& p, const scene::Scene& s);

/// Width the keel meets on the pier: the pier's diameter 2 r(z) (neck, cone, shaft:
/// mesh::pier_radius_at; 0 above or below the pier) weighted by the plug-failure pressure
/// p(d) = mu_phi^2 gamma_e d + 2 c mu_phi at depth d below the keel's top, over the keel's
/// depth range z_top > z > z_top - h_k (pier frame, m):
///   w_k = integral(2 r p dz) / integral(p dz).
/// With a constant width this is that width, and the Dolgopolov load's leading factor
/// h_k w_k (h_k mu_phi gamma_e/2 + 2c) mu_phi equals the passive pressure integrated over the
/// real width profile. When p integrates to 0 (gamma_e = c = 0) it is the mean width.
/// Exact (Simpson's rule on each piece where r is linear).
double keel_width_on_pier(const mesh::PierParams& p, double z_top, double h_k, double mu_phi, double gamma_e,
                          double cohesion);

}  // namespace hs::sim

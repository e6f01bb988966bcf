// End-of-run analysis: the pieces the ice broke into, the ISO 19906 estimate beside the
// simulated load, and the hybrid system's outcome; stored as /analysis in the run file
// (docs/output.md).
#pragma once

#include "analysis/iso19906.h"
#include "analysis/pieces.h"
#include "bridge/hybrid.h"
#include "scene/scene.h"
#include "sim/cost.h"
#include "sim/iso_inputs.h"
#include "sim/recorder.h"
#include "sim/simulation.h"
#include "sim/relaxation_cache.h"

#include <cstdint>
#include <optional>
#include <string>

namespace hs::par {
class Comm;
}

namespace hs::sim {

struct RunReport {
  analysis::Pieces pieces;     ///< rank 0 only
  double L_c = 0.0;            ///< m, characteristic length of the (consolidated) ice
  std::string L_c_note;        ///< why L_c is not defined (zero gravity); then L_c is not written
  bool has_iso = false;
  analysis::IsoInputs iso_in;  ///< rubble height = the peak ISO-consistent pile height (sim/iso_inputs.h)
  std::vector<IsoInputRecord> iso_records;  ///< every input with its unit and source
  analysis::IsoResult iso;
  /// F_H with the old pile height (the single highest particle, /series/pile_height) in place
  /// of the ISO-consistent one, for comparison; 0 when not computed.
  double iso_F_H_top_particle = 0.0;
  std::string iso_note;        ///< why there is no ISO estimate (a pier scene whose inputs ISO refuses)
  /// The estimate with the ridge file's keel frozen at the cone base (IsoMeasured::keel_depth_limit,
  /// the paper's Fig. 7 "frozen at 4 m"): only when the keel reaches deeper than the cone base.
  bool has_iso_frozen = false;
  double iso_frozen_depth = 0.0;  ///< m below the waterline, cone_base_depth
  analysis::IsoResult iso_frozen;
  analysis::IsoInputs iso_frozen_in;  ///< its inputs (keel_depth the frozen one)
  /// The pile at the load peak the estimate used (rank 0; absent without a pier or on other ranks).
  std::optional<PileAtLoadPeak> at_peak;
  double dem_peak = 0.0;       ///< N, peak horizontal force on the structure (output-row means)
  double max_pile = 0.0;       ///< m, peak of /series/pile_height (highest particle)
  bool has_pile_mean = false;
  double max_pile_mean = 0.0;  ///< m, peak of /series/pile_height_mean
  double max_pile_mean_time = 0.0;  ///< s, when it peaked
  bool has_hybrid = false;
  bridge::HybridReport hybrid;
  std::uint64_t block_bonds_broken = 0;  ///< block-particle freeze bonds broken
  std::string conversion;                ///< the scene's conversion mode
  bridge::RelaxReport relax;             ///< the relaxation before the freeze (relax.ran = 0: none)
  RelaxationOrigin relax_origin;         ///< where it came from (computed, loaded, checkpoint)
  /// At the end of the run (the at-rest check, docs/bridge.md "Relaxation"): fastest rigid block
  /// (centre speed + |omega| x half diagonal) and fastest particle (all ranks), m/s.
  double final_max_block_speed = 0.0, final_max_particle_speed = 0.0;
  /// The at-rest check's figures: the largest mean speed of a block, and of a particle, over the
  /// last rest_window s (m/s; RunFigures, recorders.cpp RestWindow); rest_window 0: not measured.
  double rest_window = 0.0, final_mean_block_speed = 0.0, final_mean_particle_speed = 0.0;
  /// Wall time by phase, reduced over the ranks (the caller fills it after analyse_run, whose own
  /// time it includes).
  RunCost cost;
};

/// Analyses the finished run. Collective: every rank calls it; the particles and bonds are
/// gathered on rank 0, which alone gets the pieces.
/// `at_peak`: the pile at the load peak (sim/metrics.h, read from the closed run file on rank 0),
/// which gives ISO its h_r, slope and porosity (sim/iso_inputs.h).
RunReport analyse_run(const Simulation& sim, const scene::Scene& s, const RunFigures& f, const par::Comm& comm,
                      const std::optional<PileAtLoadPeak>& at_peak = std::nullopt);

/// What a run's DEM/ISO ratios are judged against, as printed and stored:
/// "DEM/ISO (F_H + F_K)" (a keel; "DEM/ISO (F_H, no keel)" without), and with the keel frozen at
/// the cone base "DEM/ISO (keel frozen at 4 m)" (m below the waterline).
std::string yardstick(const RunReport& a);
std::string frozen_yardstick(const RunReport& a);

/// Adds /analysis (pieces, iso, hybrid, relaxation, cost) to the closed run file. Rank 0 only.
void write_analysis(const std::string& path, const RunReport& r);

}  // namespace hs::sim

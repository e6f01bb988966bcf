// End-of-run analysis: the pieces the ice broke into, the ISO 19906 estimate beside the
// simulated load, and the hybrid system's outcome; stored as /analysis in the run file
// (docs/output.md).
#pragma once

#include "analysis/iso19906.h"
#include "analysis/pieces.h"
#include "bridge/hybrid.h"
#include "scene/scene.h"
#include "sim/iso_inputs.h"
#include "sim/recorder.h"
#include "sim/simulation.h"

#include <cstdint>
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
  double dem_peak = 0.0;       ///< N, peak horizontal force on the structure (output-row means)
  double max_pile = 0.0;       ///< m, peak of /series/pile_height (highest particle)
  bool has_pile_mean = false;
  double max_pile_mean = 0.0;  ///< m, peak of /series/pile_height_mean
  bool has_hybrid = false;
  bridge::HybridReport hybrid;
  std::uint64_t block_bonds_broken = 0;  ///< block-particle freeze bonds broken
  std::string conversion;                ///< the scene's conversion mode
  bridge::RelaxReport relax;             ///< the relaxation before the freeze (relax.ran = 0: none)
  /// At the end of the run (the at-rest check, docs/bridge.md "Relaxation"): fastest rigid block
  /// (centre speed + |omega| x half diagonal) and fastest particle (all ranks), m/s.
  double final_max_block_speed = 0.0, final_max_particle_speed = 0.0;
  /// The at-rest check's figures: the largest mean speed of a block, and of a particle, over the
  /// last rest_window s (m/s; RunFigures, recorders.cpp RestWindow); rest_window 0: not measured.
  double rest_window = 0.0, final_mean_block_speed = 0.0, final_mean_particle_speed = 0.0;
};

/// Analyses the finished run. Collective: every rank calls it; the particles and bonds are
/// gathered on rank 0, which alone gets the pieces.
RunReport analyse_run(const Simulation& sim, const scene::Scene& s, const RunFigures& f, const par::Comm& comm);

/// Adds /analysis (pieces, iso, hybrid) to the closed run file. Rank 0 only.
void write_analysis(const std::string& path, const RunReport& r);

}  // namespace hs::sim

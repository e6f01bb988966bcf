// The progress of a run on stderr: a single updating line on a terminal (every 0.5 s), a log
// line every ~10 s otherwise, with the step rate and the time left.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>

namespace hs::sim {
class Simulation;
}

namespace hs::app {

class ProgressLine {
 public:
  ProgressLine(std::FILE* out, double duration, std::uint64_t total_steps);
  /// The run goes on from step `k` (a restart): the step rate counts the steps from there.
  void start_at(std::uint64_t k) {
    last_step_ = k;
    last_ = Clock::now();  // (the restart's reading is not stepping time)
  }
  /// After step k: prints when it is time to (checks the clock every 64 steps).
  void update(std::uint64_t k, const sim::Simulation& sim);
  /// Ends the updating line (if one is open).
  void end();

 private:
  using Clock = std::chrono::steady_clock;
  std::FILE* out_;
  double duration_;
  std::uint64_t total_;
  bool tty_;
  Clock::time_point t0_, last_;
  std::uint64_t last_step_ = 0;
  double rate_ = 0.0;  ///< steps/s, smoothed
  bool open_ = false;
};

}  // namespace hs::app

// The progress of a run on stderr: a single updating line on a terminal (every 0.5 s), a log
// line every ~10 s otherwise, with the step rate and the time left.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>

namespace hs::bonded {
class Engine;
}

namespace hs::app {

class ProgressLine {
 public:
  ProgressLine(std::FILE* out, double duration, std::uint64_t total_steps);
  /// After step k: prints when it is time to (checks the clock every 64 steps).
  void update(std::uint64_t k, const bonded::Engine& e);
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

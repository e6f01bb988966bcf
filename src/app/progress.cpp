#include "app/progress.h"

#include "app/text.h"
#include "sim/simulation.h"

#include <unistd.h>

#include <algorithm>

namespace hs::app {

ProgressLine::ProgressLine(std::FILE* out, double duration, std::uint64_t total_steps)
    : out_(out), duration_(duration), total_(total_steps), tty_(isatty(fileno(out)) != 0), t0_(Clock::now()),
      last_(t0_) {}

void ProgressLine::update(std::uint64_t k, const sim::Simulation& sim) {
  if ((k & 63) != 0 && k != total_) return;
  const auto now = Clock::now();
  const double since = std::chrono::duration<double>(now - last_).count();
  const double interval = tty_ ? 0.5 : 10.0;
  if (!(since >= interval || (k == total_ && tty_))) return;
  const double inst = (k - last_step_) / std::max(since, 1e-9);
  rate_ = rate_ == 0.0 ? inst : 0.5 * rate_ + 0.5 * inst;
  const double left = (total_ - k) / std::max(rate_, 1e-9);
  const double elapsed = std::chrono::duration<double>(now - t0_).count();
  const sim::Progress p = sim.progress();
  const auto broken = static_cast<unsigned long long>(p.bonds_broken);
  if (tty_) {
    std::fprintf(out_, "\r  t = %.4g / %g s  step %llu/%llu  %.0f steps/s  %s left  bonds broken %llu   ", p.time,
                 duration_, static_cast<unsigned long long>(k), static_cast<unsigned long long>(total_), rate_,
                 duration_text(left).c_str(), broken);
    open_ = true;
  } else {
    std::fprintf(out_, "[%s] t = %.4g / %g s, step %llu/%llu, %.0f steps/s, %s left, bonds broken %llu\n",
                 duration_text(elapsed).c_str(), p.time, duration_, static_cast<unsigned long long>(k),
                 static_cast<unsigned long long>(total_), rate_, duration_text(left).c_str(), broken);
  }
  std::fflush(out_);
  last_ = now;
  last_step_ = k;
}

void ProgressLine::end() {
  if (open_) std::fprintf(out_, "\n");
  open_ = false;
}

}  // namespace hs::app

// Graceful stop of a run on SIGINT (Ctrl-C) and SIGTERM (kill, a batch system's wall-time limit,
// mpirun forwarding either). The handler only records the signal (async-signal-safe); the run
// loop polls received() once per step, finishes that step, writes and closes the file and exits
// with 128 + signal (README, "Exit codes"; docs/output.md, "What survives a killed run").
#pragma once

#include <csignal>
#include <cstdint>

namespace hs::app {

/// Installs the SIGINT and SIGTERM handlers for its lifetime (the previous dispositions come back
/// in the destructor). Each handler is one-shot (SA_RESETHAND): a second signal of the same kind
/// while the step finishes ends the process the default way, as it would without the handler.
/// One instance at a time (the flag is process-wide).
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  /// The first SIGINT or SIGTERM received since construction, 0 if none.
  int received() const;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

/// Test hook (docs/output.md, "What survives a killed run"): with HYBRIDSIM_TEST_SIGNAL set to
/// "<INT|TERM|KILL>:<loop|relax>:<step>[:<rank>]", the run raises that signal to itself when
/// `where` ("loop": after main-loop step `step`; "relax": at the relaxation's rigid step `step`)
/// reaches the step, on every rank or on the given one only. Lets the tests stop a run at a
/// point of its progress instead of after a wall-clock sleep. Does nothing when unset.
void raise_test_signal(const char* where, std::uint64_t step, int rank);

/// "SIGINT", "SIGTERM" or "signal N".
const char* signal_name(int sig);

}  // namespace hs::app

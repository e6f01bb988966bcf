#include "app/stop_signal.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace hs::app {

namespace {

volatile std::sig_atomic_t g_received = 0;

extern "C" void record_stop_signal(int sig) {
  if (g_received == 0) g_received = sig;  // only a store: async-signal-safe
}

}  // namespace

StopSignals::StopSignals() {
  g_received = 0;
  struct sigaction sa {};
  sa.sa_handler = record_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESETHAND | SA_RESTART;  // one-shot; interrupted reads/writes are restarted
  sigaction(SIGINT, &sa, &old_int_);
  sigaction(SIGTERM, &sa, &old_term_);
}

StopSignals::~StopSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

int StopSignals::received() const { return g_received; }

void raise_test_signal(const char* where, std::uint64_t step, int rank) {
  static const char* const spec = std::getenv("HYBRIDSIM_TEST_SIGNAL");
  if (spec == nullptr) return;
  char sig[8] = {}, at[8] = {};
  unsigned long long n = 0;
  int r = -1;
  if (std::sscanf(spec, "%7[A-Z]:%7[a-z]:%llu:%d", sig, at, &n, &r) < 3) return;
  if (step != n || std::strcmp(at, where) != 0 || (r >= 0 && r != rank)) return;
  std::raise(std::strcmp(sig, "INT") == 0 ? SIGINT : std::strcmp(sig, "KILL") == 0 ? SIGKILL : SIGTERM);
}

const char* signal_name(int sig) {
  if (sig == SIGINT) return "SIGINT";
  if (sig == SIGTERM) return "SIGTERM";
  static char buf[32];
  std::snprintf(buf, sizeof buf, "signal %d", sig);
  return buf;
}

}  // namespace hs::app

// Shared by the tests that run the hybridsim binary as a user would (test_cli, test_stop,
// test_input_guards): a per-process work directory, file helpers, and one run of the binary with
// its exit code and output.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace hs::testing {

namespace fs = std::filesystem;

/// The outcome of one `hybridsim` run: exit code (128 + signal if killed by one), stdout, stderr.
struct CliResult {
  int rc = -1;
  std::string out, err;
};

/// <tmp>/hs_test_<tag>_<pid>, created if needed: one directory per test executable and process.
inline fs::path cli_work_dir(const std::string& tag) {
  const fs::path d = fs::temp_directory_path() / ("hs_test_" + tag + "_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// "export HYBRIDSIM_CACHE='<dir>/relaxation-cache-<n>' && ", a new directory for every call: a
/// run started after it neither reads nor writes the user's relaxation cache (docs/bridge.md, "The
/// relaxation cache"), and finds no other run's relaxation unless the test names a shared one.
inline std::string fresh_cache_env(const fs::path& dir) {
  static int calls = 0;
  const fs::path cache = dir / ("relaxation-cache-" + std::to_string(::getpid()) + "-" + std::to_string(++calls));
  return "export HYBRIDSIM_CACHE='" + cache.string() + "' && ";
}

/// Runs `hybridsim <args>` in `dir` through /bin/sh, after `prefix` (e.g. "ulimit -v N && "),
/// with a fresh relaxation cache (fresh_cache_env) unless `prefix` sets HYBRIDSIM_CACHE itself.
inline CliResult run_hybridsim(const fs::path& dir, const std::string& args, const std::string& prefix = "") {
  const std::string cache = prefix.find("HYBRIDSIM_CACHE") == std::string::npos ? fresh_cache_env(dir) : "";
  const std::string cmd =
      "cd '" + dir.string() + "' && " + cache + prefix + "'" HYBRIDSIM_EXE "' " + args + " > out.txt 2> err.txt";
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  r.out = slurp(dir / "out.txt");
  r.err = slurp(dir / "err.txt");
  return r;
}

/// "mpirun -np <np> " with the flags the tests need (allowed as root in CI containers; ranks may
/// share a core and yield it while waiting, as tests/CMakeLists.txt), to put before a command.
inline std::string mpirun_prefix(int np) {
  // Under AddressSanitizer (scripts/test-sanitizers.sh) the ranks run without LeakSanitizer:
  // at the exit of a rank that stops early (exit 2 on bad input, 143 on SIGTERM) with Open MPI's
  // threads still up, LeakSanitizer's tracer crashes ("Tracer caught signal 11 ... LeakSanitizer
  // has encountered a fatal error") or reports Open MPI's nameless allocations. The serial CLI
  // runs and the MPI unit tests (the script's second pass) keep the leak check.
#if defined(__SANITIZE_ADDRESS__)
  const std::string lsan_off = "env \"ASAN_OPTIONS=$ASAN_OPTIONS:detect_leaks=0\" ";
#else
  const std::string lsan_off;
#endif
  return lsan_off + "env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_mpi_yield_when_idle=1 '" HYBRIDSIM_MPIEXEC
         "' -np " + std::to_string(np) + " --oversubscribe --bind-to none ";
}

}  // namespace hs::testing

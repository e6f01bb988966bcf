#include "app/study_runner.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <stdexcept>

namespace hs::app {

namespace {

volatile std::sig_atomic_t g_stop = 0;

extern "C" void record_study_stop(int sig) {
  if (g_stop == 0) g_stop = sig;
}

/// SIGINT/SIGTERM recorded, without SA_RESTART so that wait4 returns EINTR; restored on scope exit.
class StudyStopSignals {
 public:
  StudyStopSignals() {
    g_stop = 0;
    struct sigaction sa {};
    sa.sa_handler = record_study_stop;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~StudyStopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StudyStopSignals(const StudyStopSignals&) = delete;
  StudyStopSignals& operator=(const StudyStopSignals&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

/// In the child: its own process group, stdout/stderr appended to the log, exec. Never returns.
[[noreturn]] void exec_child(const StudyJob& job) {
  setpgid(0, 0);
  const int fd = ::open(job.log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd >= 0) {
    dup2(fd, STDOUT_FILENO);
    dup2(fd, STDERR_FILENO);
  }
  std::vector<char*> argv;
  for (const std::string& a : job.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  execvp(argv[0], argv.data());
  std::fprintf(stderr, "hybridsim study: cannot start '%s': %s\n", argv[0], std::strerror(errno));
  _exit(127);
}

struct Running {
  const StudyJob* job;
  std::chrono::steady_clock::time_point start;
};

StudyJobEnd job_end(int status, const rusage& ru, const Running& r, bool stopped) {
  StudyJobEnd e;
  e.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  e.stopped = stopped;
  e.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - r.start).count();
  e.core_seconds = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
                   1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  e.max_rss_mib = static_cast<double>(ru.ru_maxrss) / 1024.0;  // KiB on Linux
  return e;
}

}  // namespace

int run_study_jobs(const std::vector<StudyJob>& queue, int jobs, const std::function<void(const StudyJob&)>& started,
                   const std::function<void(const StudyJob&, const StudyJobEnd&)>& ended) {
  const StudyStopSignals signals;
  std::map<pid_t, Running> running;
  std::size_t next = 0;
  bool passed_on = false;
  while (next < queue.size() || !running.empty()) {
    while (g_stop == 0 && next < queue.size() && running.size() < static_cast<std::size_t>(std::max(1, jobs))) {
      const StudyJob& job = queue[next++];
      std::fflush(nullptr);
      const pid_t pid = fork();
      if (pid < 0) throw std::runtime_error(std::string("hybridsim study: fork failed: ") + std::strerror(errno));
      if (pid == 0) exec_child(job);
      running[pid] = {&job, std::chrono::steady_clock::now()};
      started(job);
    }
    if (running.empty()) break;
    if (g_stop != 0 && !passed_on) {
      for (const auto& [p, r] : running) kill(p, SIGTERM);
      passed_on = true;
    }
    int status = 0;
    rusage ru{};
    const pid_t pid = wait4(-1, &status, 0, &ru);
    if (pid < 0) {
      if (errno != EINTR) throw std::runtime_error(std::string("hybridsim study: wait4: ") + std::strerror(errno));
      continue;  // a signal: passed on above

    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    const Running r = it->second;
    running.erase(it);
    ended(*r.job, job_end(status, ru, r, passed_on));
  }
  return g_stop;
}

}  // namespace hs::app

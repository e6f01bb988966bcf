#include "app/output_lock.h"

#include "common/error.h"
#include "parallel/comm.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace hs::app {

namespace {

namespace fs = std::filesystem;

/// /proc/<pid>/cmdline with its NULs as spaces ("" where /proc does not have it).
std::string proc_cmdline(const std::string& pid) {
  std::ifstream in("/proc/" + pid + "/cmdline", std::ios::binary);
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  while (!s.empty() && s.back() == '\0') s.pop_back();
  for (char& c : s)
    if (c == '\0') c = ' ';
  return s;
}

/// What the lock file says: "<pid>\n<command line>\n".
std::string read_all(int fd) {
  std::string s;
  char buf[4096];
  off_t at = 0;
  for (ssize_t n; (n = ::pread(fd, buf, sizeof buf, at)) > 0; at += n) s.append(buf, static_cast<std::size_t>(n));
  return s;
}

/// "process 1234 (hybridsim run a.json -o out.h5)": the holder as its lock file and /proc give
/// it. The holder writes its PID just after it takes the lock: an empty file is read again for
/// up to half a second.
std::string describe_holder(int fd) {
  std::string text = read_all(fd);
  for (int k = 0; k < 50 && text.empty(); ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    text = read_all(fd);
  }
  std::istringstream in(text);
  std::string pid, cmd;
  std::getline(in, pid);
  std::getline(in, cmd);
  if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos) return "another process";
  const std::string live = proc_cmdline(pid);
  if (!live.empty()) cmd = live;
  return "process " + pid + (cmd.empty() ? std::string() : " (" + cmd + ")");
}

/// Takes the lock of `f` into `out`; returns the refusal's message ("" when taken).
std::string take(const LockedFile& f, int& out_fd) {
  const std::string lock = lock_path_of(f.path);
  // A holder removes its lock file as it ends: a lock taken on a file that has just been removed
  // (its inode no longer at the path) is no lock, and is taken again on the new file.
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
      return "cannot create the lock file '" + lock + "' beside " + f.what + " '" + f.path +
             "': " + std::strerror(errno) + "; choose another output path with -o";
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      std::string msg;
      if (e == EWOULDBLOCK)
        msg = f.what + " '" + f.path + "' is in use by another running hybridsim: " + describe_holder(fd) +
              " holds '" + lock + "'. Wait for that run to end (or stop it), or choose another output path with -o";
      else
        msg = "cannot lock '" + lock + "': " + std::strerror(e) + "; choose another output path with -o";
      ::close(fd);
      return msg;
    }
    struct stat open_st {}, path_st {};
    if (::fstat(fd, &open_st) == 0 && ::stat(lock.c_str(), &path_st) == 0 && open_st.st_ino == path_st.st_ino &&
        open_st.st_dev == path_st.st_dev) {
      std::string me = std::to_string(::getpid()) + "\n" + proc_cmdline("self") + "\n";
      if (::ftruncate(fd, 0) == 0 && ::pwrite(fd, me.data(), me.size(), 0) < 0) {
        // The PID is for messages only: the flock is the lock.
      }
      out_fd = fd;
      return "";
    }
    ::close(fd);
  }
  return "cannot hold the lock file '" + lock + "': it is removed and made again continually; choose another "
         "output path with -o";
}

}  // namespace

std::string lock_path_of(const std::string& path) { return path + ".lock"; }

OutputLocks::OutputLocks(const std::vector<LockedFile>& files, const par::Comm& comm) {
  std::string refusal, option;
  if (comm.rank() == 0) {
    std::vector<std::string> seen;
    for (const LockedFile& f : files) {
      std::error_code ec;
      const std::string key = fs::weakly_canonical(fs::absolute(lock_path_of(f.path)), ec).string();
      if (std::find(seen.begin(), seen.end(), key) != seen.end()) continue;
      seen.push_back(key);
      int fd = -1;
      refusal = take(f, fd);
      if (!refusal.empty()) {
        option = f.option;
        break;
      }
      held_.push_back({fd, lock_path_of(f.path)});
    }
  }
  if (comm.parallel()) {
    refusal = comm.broadcast(refusal);
    option = comm.broadcast(option);
  }
  if (!refusal.empty()) {
    release();
    throw InputError(option, refusal);
  }
}

OutputLocks::OutputLocks(OutputLocks&& o) noexcept : held_(std::move(o.held_)) { o.held_.clear(); }

OutputLocks& OutputLocks::operator=(OutputLocks&& o) noexcept {
  if (this != &o) {
    release();
    held_ = std::move(o.held_);
    o.held_.clear();
  }
  return *this;
}

OutputLocks::~OutputLocks() { release(); }

std::vector<std::string> OutputLocks::held() const {
  std::vector<std::string> v;
  for (const Held& h : held_) v.push_back(h.lock_path);
  return v;
}

void OutputLocks::release() noexcept {
  // Removed while still held, so that no other process takes a lock on a file about to vanish
  // without seeing it vanish (take() checks the inode).
  for (const Held& h : held_) {
    ::unlink(h.lock_path.c_str());
    ::close(h.fd);
  }
  held_.clear();
}

}  // namespace hs::app

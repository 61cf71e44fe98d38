#include "vdrig/core/process_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

namespace vdrig {
namespace fs = std::filesystem;

namespace {

/// The PID the holder wrote, or "?" (it writes it just after locking: a refusal in that instant waits a little).
std::string written_pid(int fd) {
  for (int attempt = 0; attempt < 20; ++attempt) {
    char buf[32] = {};
    const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
    if (n > 0) {
      std::string pid(buf, static_cast<size_t>(n));
      while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
      if (!pid.empty()) return pid;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return "?";
}

/// The PID holding an flock on the file open as `fd`, from /proc/locks ("1: FLOCK ADVISORY WRITE <pid>
/// <major>:<minor>:<inode> 0 EOF", device numbers in hex), or "?". A device node cannot hold a PID of its own.
std::string flock_holder(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return "?";
  std::ifstream locks("/proc/locks");
  std::string line, by_inode_only;
  while (std::getline(locks, line)) {
    std::istringstream fields(line);
    std::string ordinal, kind, advisory, mode, pid, where;
    fields >> ordinal >> kind;
    if (kind == "->") continue;  // a waiter, not a holder
    if (kind != "FLOCK" || !(fields >> advisory >> mode >> pid >> where)) continue;
    unsigned major_dev = 0, minor_dev = 0;
    unsigned long long inode = 0;
    if (std::sscanf(where.c_str(), "%x:%x:%llu", &major_dev, &minor_dev, &inode) != 3 || inode != st.st_ino) continue;
    if (major_dev == ::major(st.st_dev) && minor_dev == ::minor(st.st_dev)) return pid;
    // Stacked file systems (overlayfs) report another device than stat does; the inode alone is a good guess.
    by_inode_only = pid;
  }
  return by_inode_only.empty() ? "?" : by_inode_only;
}

/// flock(LOCK_EX | LOCK_NB), retried on EINTR; 0 or the errno.
int try_flock(int fd) {
  int rc;
  while ((rc = ::flock(fd, LOCK_EX | LOCK_NB)) != 0 && errno == EINTR) {
  }
  return rc == 0 ? 0 : errno;
}

/// An existing or newly made folder any process may create lock files in.
bool usable_lock_dir(const fs::path& dir) {
  if (::mkdir(dir.c_str(), 01777) == 0) {
    ::chmod(dir.c_str(), 01777);  // mkdir's mode is cut by the umask
  } else if (errno != EEXIST) {
    return false;
  }
  struct stat st {};
  return ::stat(dir.c_str(), &st) == 0 && S_ISDIR(st.st_mode) && ::access(dir.c_str(), W_OK | X_OK) == 0;
}

}  // namespace

Result<ProcessLock> ProcessLock::acquire(const fs::path& file, const std::string& what, ErrorCode held) {
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) return make_error(ErrorCode::kIo, "cannot open lock file " + file.string() + ": " + std::strerror(errno));
  if (const int err = try_flock(fd); err != 0) {
    if (err == EWOULDBLOCK) {
      const std::string pid = written_pid(fd);
      ::close(fd);
      return make_error(held, what + " is in use by PID " + pid);
    }
    ::close(fd);
    return make_error(ErrorCode::kIo, "cannot lock " + file.string() + ": " + std::strerror(err));
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    const int err = errno;
    ::close(fd);
    return make_error(ErrorCode::kIo, "cannot write " + file.string() + ": " + std::strerror(err));
  }
  return ProcessLock(fd);
}

ProcessLock& ProcessLock::operator=(ProcessLock&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

ProcessLock::~ProcessLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor of the open file releases the flock
}

Status lock_open_file(int fd, const std::string& what) {
  const int err = try_flock(fd);
  if (err == 0) return Status::ok();
  if (err == EWOULDBLOCK) return make_error(ErrorCode::kInUse, what + " is in use by PID " + flock_holder(fd));
  return make_error(ErrorCode::kIo, "cannot lock " + what + ": " + std::strerror(err));
}

Result<fs::path> device_lock_dir() {
  for (const char* dir : {"/run/lock/vdrig", "/tmp/vdrig-locks"})
    if (usable_lock_dir(dir)) return fs::path(dir);
  return make_error(ErrorCode::kIo,
                    "no folder for device locks: neither /run/lock/vdrig nor /tmp/vdrig-locks can be "
                    "created or written");
}

Result<ProcessLock> lock_device(const std::string& device) {
  auto dir = device_lock_dir();
  if (!dir) return dir.error();
  std::string name = device;
  for (char& c : name) {
    const bool safe =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!safe) c = '_';
  }
  return ProcessLock::acquire(dir.value() / (name + ".lock"), device);
}

}  // namespace vdrig

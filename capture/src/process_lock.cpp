#include "vdrig/capture/process_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <thread>

#include "vdrig/capture/session_layout.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;

namespace {

/// The PID the holder wrote, or "?" (it writes it just after locking: a refusal in that instant waits a little).
std::string holder_pid(int fd) {
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

}  // namespace

Result<ProcessLock> ProcessLock::acquire(const fs::path& file, const std::string& what) {
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) return make_error(ErrorCode::kIo, "cannot open lock file " + file.string() + ": " + std::strerror(errno));
  int rc;
  while ((rc = ::flock(fd, LOCK_EX | LOCK_NB)) != 0 && errno == EINTR) {
  }
  if (rc != 0) {
    const int err = errno;
    if (err == EWOULDBLOCK) {
      const std::string pid = holder_pid(fd);
      ::close(fd);
      return make_error(ErrorCode::kInvalidArgument, what + " is in use by PID " + pid);
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

Result<ProcessLock> lock_session(const fs::path& session_dir) {
  return ProcessLock::acquire(SessionLayout(session_dir).lock_file(), "session " + session_dir.string());
}

std::optional<std::string> rig_lock_name(const nlohmann::json& rig_config) {
  std::string name;
  if (!rig_config.is_object()) return std::nullopt;
  if (const auto it = rig_config.find("lock"); it != rig_config.end() && it->is_string()) {
    name = it->get<std::string>();
  } else if (const auto st = rig_config.find("stage"); st != rig_config.end() && st->is_object()) {
    auto text = [&](const char* key) {
      const auto f = st->find(key);
      return f != st->end() && (f->is_string() || f->is_number()) ? (f->is_string() ? f->get<std::string>() : f->dump())
                                                                  : std::string();
    };
    if (!text("device").empty())
      name = text("device");
    else if (!text("host").empty())
      name = text("host") + ":" + (text("port").empty() ? std::string("502") : text("port"));
    else if (!text("chip").empty())
      name = text("chip");
  }
  if (name.empty()) return std::nullopt;
  for (char& c : name) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok) c = '_';
  }
  return name;
}

Result<std::optional<ProcessLock>> lock_rig(const nlohmann::json& rig_config, const fs::path& runtime_dir) {
  const auto name = rig_lock_name(rig_config);
  if (!name) return std::optional<ProcessLock>();
  std::error_code ec;
  fs::create_directories(runtime_dir, ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + runtime_dir.string() + ": " + ec.message());
  auto lock = ProcessLock::acquire(runtime_dir / ("rig-" + *name + ".lock"), "rig " + *name);
  if (!lock) return lock.error();
  return std::optional<ProcessLock>(std::move(lock.value()));
}

}  // namespace vdrig::capture

// ProcessLock: "only one process does this at a time", held as an flock(LOCK_EX | LOCK_NB) on a lock file. The
// kernel releases the lock when the holder's file descriptor closes, including when the process dies (SIGKILL, a
// crash), so a dead holder never leaves a stale lock; the file itself stays and is simply locked again. The holder
// writes its PID into the file after locking, and a refused process names it: "session S is in use by PID n".
//
// Two locks guard a capture (docs/protocol.md, "Locks"):
//   - the session: SessionLayout::lock_file(), taken by whoever captures into the session (run_capture takes it for
//     the run unless the caller holds it; `vdrig capture --resume` and vdrigd take it before replaying the journal);
//   - the rig: <runtime dir>/rig-<name>.lock, taken by whoever drives the rig (vdrigd while it holds the rig, the
//     CLI for its capture). rig_lock_name() says which rigs are locked and by which name.
// Locks of one file conflict also within one process (every acquire opens the file anew).
#pragma once

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::capture {

class ProcessLock {
 public:
  /// Creates `file` if missing (0644; its folder must exist), locks it without waiting and writes this process's PID
  /// into it. Held: the lock. Held elsewhere: kInvalidArgument "<what> is in use by PID n". Other failures: kIo.
  static Result<ProcessLock> acquire(const std::filesystem::path& file, const std::string& what);

  ProcessLock(ProcessLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  ProcessLock& operator=(ProcessLock&& other) noexcept;
  ProcessLock(const ProcessLock&) = delete;
  ProcessLock& operator=(const ProcessLock&) = delete;
  ~ProcessLock();  // releases the lock (the file stays)

 private:
  explicit ProcessLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

/// Locks the session in `session_dir` for capturing (SessionLayout::lock_file()); the error names the session.
Result<ProcessLock> lock_session(const std::filesystem::path& session_dir);

/// Which rig a rig config drives, for its lock: the config's top-level "lock" string when given; else the stage's
/// device ("device" of a serial stage, "host:port" of a TCP stage, "chip" of a GPIO stage); else nullopt: a rig
/// without a named device (the simulator) is not locked. The name is made file-safe ([A-Za-z0-9._-], others '_').
std::optional<std::string> rig_lock_name(const nlohmann::json& rig_config);

/// Locks the rig `rig_config` drives in `runtime_dir` (created if missing, never chmod'ed). nullopt (nothing held)
/// for a rig rig_lock_name() does not lock.
Result<std::optional<ProcessLock>> lock_rig(const nlohmann::json& rig_config, const std::filesystem::path& runtime_dir);

}  // namespace vdrig::capture

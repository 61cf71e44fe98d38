// ProcessLock: "only one process does this at a time", held as an flock(LOCK_EX | LOCK_NB) on a lock file. The
// kernel releases the lock when the holder's file descriptor closes, including when the process dies (SIGKILL, a
// crash), so a dead holder never leaves a stale lock; the file itself stays and is simply locked again. The holder
// writes its PID into the file after locking, and a refused process names it: "session S is in use by PID n".
// Locks of one file conflict also within one process (every acquire opens the file anew).
//
// Devices are locked where every process finds them, whatever its runtime folder (docs/hardware.md, "Locks"):
//   - a device with a node (a serial port, a GPIO chip): flock on the opened node itself (lock_open_file), as other
//     Linux tools that share serial ports expect;
//   - a device without one (a Modbus TCP drive): a lock file in device_lock_dir() named from its address
//     (lock_device).
// Sessions are locked in their folder (capture/process_lock.hpp).
#pragma once

#include <filesystem>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig {

class ProcessLock {
 public:
  /// Creates `file` if missing (0644; its folder must exist), locks it without waiting and writes this process's PID
  /// into it. Held elsewhere: `held` (kInUse unless a caller's protocol documents another code) "<what> is in use by
  /// PID n". Other failures: kIo.
  static Result<ProcessLock> acquire(const std::filesystem::path& file, const std::string& what,
                                     ErrorCode held = ErrorCode::kInUse);

  ProcessLock(ProcessLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  ProcessLock& operator=(ProcessLock&& other) noexcept;
  ProcessLock(const ProcessLock&) = delete;
  ProcessLock& operator=(const ProcessLock&) = delete;
  ~ProcessLock();  // releases the lock (the file stays)

 private:
  explicit ProcessLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

/// Locks the file or device node open as `fd` (owned by the caller or its device library) with
/// flock(LOCK_EX | LOCK_NB). The lock lives with that open file: closing `fd` releases it, so a device reopened after
/// a lost link must be locked again. Held elsewhere: kInUse "<what> is in use by PID n" (the PID from /proc/locks;
/// "?" when the holder is not visible from here). Other failures: kIo.
Status lock_open_file(int fd, const std::string& what);

/// The folder of the lock files of devices without a node and of named rigs: /run/lock/vdrig, or /tmp/vdrig-locks
/// when that cannot be created or written. A fixed place, not the runtime folder: two processes started with
/// different runtime folders must still see each other's locks. Created mode 1777 (as /run/lock and /tmp are) so
/// that the processes of every user lock there. kIo when neither is usable.
Result<std::filesystem::path> device_lock_dir();

/// Locks `device` ("modbus-tcp drive 192.168.0.50:502", "rig bench-1") with a lock file in device_lock_dir() whose
/// name is `device` made file-safe; the error names `device` and the holder's PID (kInUse).
Result<ProcessLock> lock_device(const std::string& device);

}  // namespace vdrig

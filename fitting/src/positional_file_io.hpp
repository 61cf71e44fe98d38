// Positional (pread/pwrite) file I/O for the observation-map files, whose writer fills a header, tiles and an index at
// offsets it computes, and whose reader shares one descriptor between threads. What core/file_write.hpp already has
// (errno mapping, fsync, the atomic rename) is used from there; this file adds only what it lacks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <utility>

#include "vdrig/core/result.hpp"

namespace vdrig::fitting {

/// Owns a file descriptor (closed on destruction or reset()).
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = std::exchange(o.fd_, -1);
    }
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd() { reset(); }
  int get() const { return fd_; }
  /// Hands the descriptor over without closing it.
  int release() { return std::exchange(fd_, -1); }
  void reset();

 private:
  int fd_ = -1;
};

/// Writes all n bytes at `offset` (pwrite, retrying EINTR and short writes). Errors "writing <path>: ..." with
/// kNoSpace for a full disk (error_from_errno).
Status write_at(int fd, const std::filesystem::path& path, const void* data, size_t n, uint64_t offset);

/// Reads exactly n bytes at `offset`; a short read means the file is shorter than its header or index says:
/// kCorrupt "<path> is truncated".
Status read_at(int fd, const std::filesystem::path& path, void* data, size_t n, uint64_t offset);

/// Opens `path` read-only (O_CLOEXEC). kNotFound when it does not exist, kIo otherwise ("opening <path>: ...").
Result<UniqueFd> open_for_reading(const std::filesystem::path& path);

/// A new file `<path>.tmp-XXXXXX` beside `path` (mkstemp: never an existing file), with the mode of vdrig's other
/// outputs (0666 less the umask): the temporary of an atomic replace, renamed over `path` by commit_temporary
/// (core/file_write.hpp). `vdrig session check` knows this name pattern (docs/sessions.md).
Result<UniqueFd> create_temporary_beside(const std::filesystem::path& path, std::filesystem::path* temporary);

/// An anonymous scratch file in `dir`: created and unlinked at once, so the kernel frees it when it is closed or
/// the process dies. `name` receives the name it had, for error messages.
Result<UniqueFd> create_anonymous_file(const std::filesystem::path& dir, std::filesystem::path* name);

}  // namespace vdrig::fitting

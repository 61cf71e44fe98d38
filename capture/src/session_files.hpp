// Opening a session's files without letting a link planted in the session redirect the access. Session folders may
// be writable by other users while vdrigd (often root) writes into them, so every file and folder below the session
// folder is opened relative to its parent's descriptor with O_NOFOLLOW: a symbolic link where a session file or
// folder belongs is an error naming it, never followed. The session folder itself is the caller's choice and is
// opened as given.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::capture::detail {

/// A file descriptor closed when the object goes.
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  UniqueFd& operator=(UniqueFd&& other) noexcept;
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd();
  int get() const { return fd_; }

 private:
  int fd_ = -1;
};

/// kInvalidArgument "<shown> is a symbolic link inside the session: refused ..." (the message every refusal uses).
Error symlink_refused(const std::filesystem::path& shown);

/// The session folder, opened O_DIRECTORY (kNotFound when missing).
Result<UniqueFd> open_session_dir(const std::filesystem::path& session_dir);

/// Folder `name` of the session folder (frames, hdr, ...), opened O_DIRECTORY | O_NOFOLLOW; created (0755) first
/// when `create`. A link there is symlink_refused(); missing (and not created) is kNotFound.
Result<UniqueFd> open_session_folder(const std::filesystem::path& session_dir, const std::string& name, bool create);

/// The folder `relative` below the session folder (empty: the session folder), each component opened O_DIRECTORY |
/// O_NOFOLLOW from its parent. Errors as open_session_folder().
Result<UniqueFd> open_session_subfolder(const std::filesystem::path& session_dir,
                                        const std::filesystem::path& relative);

/// Entry `name` of the folder `dir_fd` (shown as `shown` in errors): ok when absent or a regular file;
/// symlink_refused() for a link, kInvalidArgument for anything else.
Status check_regular_or_absent_at(int dir_fd, const std::string& name, const std::filesystem::path& shown);

/// The content of the regular file `relative` (one name, or "folder/name") of the session, opened with O_NOFOLLOW
/// at every step. Errors: kNotFound when missing, symlink_refused() for a link, kInvalidArgument for a non-regular
/// file or one larger than `max_bytes`, kIo for read failures.
Result<std::string> read_session_file(const std::filesystem::path& session_dir, const std::filesystem::path& relative,
                                      std::size_t max_bytes);

}  // namespace vdrig::capture::detail

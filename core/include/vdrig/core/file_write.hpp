// Durable file writes on POSIX: errno mapped to ErrorCode, fsync of files and folders, whole-buffer writes, and the
// atomic replace protocol (write a temporary sibling, fsync it, rename it over the target, fsync the folder) that
// every writer of a file a reader may open concurrently or after a crash follows.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig {

/// kNoSpace for ENOSPC and EDQUOT (disk or quota full: the caller may free space and retry), kIo for any other errno.
ErrorCode error_code_from_errno(int err);

/// An Error with error_code_from_errno(err) and the message "<what>: <strerror(err)>", e.g. what = "write /a/b".
Error error_from_errno(int err, const std::string& what);

/// fsync()s a file (is_dir false) or a folder (is_dir true, which makes the creations, renames and removals of its
/// entries durable). Opens it read-only with O_CLOEXEC; EINTR is retried. Errors: "open <path>: ..." or
/// "fsync <path>: ..." with the code of error_code_from_errno.
Status fsync_path(const std::filesystem::path& path, bool is_dir);
/// fsync()s the open descriptor `fd` (retried on EINTR; `path` names it in the error) and closes it, whatever the
/// outcome.
Status fsync_and_close(int fd, const std::filesystem::path& path);

/// Writes all `size` bytes at fd's current offset, retrying EINTR and continuing after short writes. Returns 0 or
/// the errno of the failure (ENOSPC when write() makes no progress: on a regular file that means the disk is full).
int write_all(int fd, const void* data, size_t size);

/// A fresh hidden name beside `path` (".<name>.tmp<random>") for the atomic replace protocol. Writers create it with
/// create_new_file(), so a link planted at the name is refused rather than followed.
std::filesystem::path temporary_sibling(const std::filesystem::path& path);

/// kInvalidArgument when `path` exists and is not a regular file: a symbolic link (whoever planted it meant the
/// write to land elsewhere), a device such as /dev/null, a FIFO, a socket or a folder. Renaming over it would replace
/// it (as root, /dev/null itself), so outputs refuse it.
Status check_replaceable(const std::filesystem::path& path);

/// kInvalidArgument naming the first symbolic link among the components of `target` below `base` (`base` itself, the
/// folder the caller chose, is not looked at; `target` must lie below it). Components that do not exist yet are fine.
/// For writers into folders other users may write to (a session): a planted link would redirect the write.
Status check_no_symlinks_below(const std::filesystem::path& base, const std::filesystem::path& target);

/// Creates `path` for writing as a new file (O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, mode 0644): never opens an
/// existing file or follows a link planted at the name. The descriptor, or the errno-mapped error naming `path`.
Result<int> create_new_file(const std::filesystem::path& path);

/// Completes the atomic replace: fsyncs the fully written `temporary`, renames it to `path` and fsyncs path's folder.
/// On failure before the rename (check_replaceable included) the temporary is removed and `path` is untouched.
Status commit_temporary(const std::filesystem::path& temporary, const std::filesystem::path& path);

/// Writes bytes to `path` through a temporary file, fsync, rename, fsync of the folder: a reader never sees a
/// partially written file. Errors: kNoSpace when the disk is full, kIo otherwise (e.g. a missing folder).
Status write_file_atomic(const std::filesystem::path& path, const std::string& bytes);

}  // namespace vdrig

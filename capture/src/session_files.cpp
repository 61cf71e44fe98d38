#include "session_files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>

#include "vdrig/core/file_write.hpp"

namespace vdrig::capture::detail {
namespace fs = std::filesystem;

UniqueFd& UniqueFd::operator=(UniqueFd&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

UniqueFd::~UniqueFd() {
  if (fd_ >= 0) ::close(fd_);
}

Error symlink_refused(const fs::path& shown) {
  return make_error(ErrorCode::kInvalidArgument,
                    shown.string() +
                        " is a symbolic link inside the session: refused (vdrig never follows links in a session; "
                        "remove it, e.g. with vdrig session check --repair)");
}

namespace {

/// What a non-regular file is, for messages (as core's read_regular_file says it).
std::string not_regular(const fs::path& shown, mode_t mode) {
  const char* kind = S_ISDIR(mode)    ? "a directory"
                     : S_ISFIFO(mode) ? "a FIFO"
                     : S_ISSOCK(mode) ? "a socket"
                     : S_ISCHR(mode)  ? "a character device"
                     : S_ISBLK(mode)  ? "a block device"
                                      : "not a regular file";
  return shown.string() + " is " + kind + ", not a regular file: refused";
}

/// Whether `name` in `dir_fd` is a symbolic link (after an open with O_NOFOLLOW failed with ELOOP or ENOTDIR).
bool is_link_at(int dir_fd, const std::string& name) {
  struct stat st {};
  return ::fstatat(dir_fd, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode);
}

Result<UniqueFd> open_folder_at(int dir_fd, const std::string& name, const fs::path& shown, bool create) {
  if (create && ::mkdirat(dir_fd, name.c_str(), 0755) != 0 && errno != EEXIST)
    return error_from_errno(errno, "create " + shown.string());
  const int fd = ::openat(dir_fd, name.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd >= 0) return UniqueFd(fd);
  const int err = errno;
  if (is_link_at(dir_fd, name)) return symlink_refused(shown);
  if (err == ENOENT) return make_error(ErrorCode::kNotFound, shown.string() + " does not exist");
  if (err == ENOTDIR) return make_error(ErrorCode::kInvalidArgument, shown.string() + " is not a folder");
  return error_from_errno(err, "open " + shown.string());
}

}  // namespace

Result<UniqueFd> open_session_dir(const fs::path& session_dir) {
  const int fd = ::open(session_dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) return UniqueFd(fd);
  if (errno == ENOENT) return make_error(ErrorCode::kNotFound, "no session at " + session_dir.string());
  return error_from_errno(errno, "open " + session_dir.string());
}

Result<UniqueFd> open_session_folder(const fs::path& session_dir, const std::string& name, bool create) {
  auto session = open_session_dir(session_dir);
  if (!session) return session.error();
  return open_folder_at(session->get(), name, session_dir / name, create);
}

Result<UniqueFd> open_session_subfolder(const fs::path& session_dir, const fs::path& relative) {
  auto folder = open_session_dir(session_dir);
  if (!folder) return folder.error();
  fs::path shown = session_dir;
  for (const auto& part : relative) {
    if (part.empty() || part == ".") continue;
    shown /= part;
    auto next = open_folder_at(folder->get(), part.string(), shown, false);
    if (!next) return next.error();
    folder = std::move(next);
  }
  return folder;
}

Status check_regular_or_absent_at(int dir_fd, const std::string& name, const fs::path& shown) {
  struct stat st {};
  if (::fstatat(dir_fd, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) {
    if (errno == ENOENT) return Status::ok();
    return error_from_errno(errno, "stat " + shown.string());
  }
  if (S_ISLNK(st.st_mode)) return symlink_refused(shown);
  if (!S_ISREG(st.st_mode)) return make_error(ErrorCode::kInvalidArgument, not_regular(shown, st.st_mode));
  return Status::ok();
}

Result<std::string> read_session_file(const fs::path& session_dir, const fs::path& relative, std::size_t max_bytes) {
  auto folder = open_session_subfolder(session_dir, relative.parent_path());
  if (!folder) return folder.error();
  const fs::path leaf = relative.filename();
  const fs::path shown = session_dir / relative;
  // O_NONBLOCK: a FIFO planted at the name must not hang the reader.
  const int fd = ::openat(folder->get(), leaf.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (is_link_at(folder->get(), leaf.string())) return symlink_refused(shown);
    if (err == ENOENT) return make_error(ErrorCode::kNotFound, shown.string() + " does not exist");
    return error_from_errno(err, "open " + shown.string());
  }
  const UniqueFd file(fd);
  struct stat st {};
  if (::fstat(fd, &st) != 0) return error_from_errno(errno, "stat " + shown.string());
  if (!S_ISREG(st.st_mode)) return make_error(ErrorCode::kInvalidArgument, not_regular(shown, st.st_mode));
  if (static_cast<std::size_t>(st.st_size) > max_bytes)
    return make_error(ErrorCode::kInvalidArgument,
                      shown.string() + " is larger than " + std::to_string(max_bytes >> 20) + " MiB: not read");
  std::string text;
  char buf[65536];
  while (true) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return error_from_errno(errno, "read " + shown.string());
    if (n == 0) break;
    text.append(buf, static_cast<size_t>(n));
    if (text.size() > max_bytes)
      return make_error(ErrorCode::kInvalidArgument, shown.string() + " grew past the read limit: not read");
  }
  return text;
}

}  // namespace vdrig::capture::detail

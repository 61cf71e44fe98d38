#include "vdrig/core/file_write.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>

namespace vdrig {
namespace fs = std::filesystem;

ErrorCode error_code_from_errno(int err) {
  return err == ENOSPC || err == EDQUOT ? ErrorCode::kNoSpace : ErrorCode::kIo;
}

Error error_from_errno(int err, const std::string& what) {
  return make_error(error_code_from_errno(err), what + ": " + std::strerror(err));
}

Status fsync_path(const fs::path& path, bool is_dir) {
  const int flags = (is_dir ? (O_RDONLY | O_DIRECTORY) : O_RDONLY) | O_CLOEXEC;
  int fd = -1;
  do fd = ::open(path.c_str(), flags);
  while (fd < 0 && errno == EINTR);
  if (fd < 0) return error_from_errno(errno, "open " + path.string());
  return fsync_and_close(fd, path);
}

Status fsync_and_close(int fd, const fs::path& path) {
  int rc = 0;
  do rc = ::fsync(fd);
  while (rc != 0 && errno == EINTR);
  const int err = errno;
  ::close(fd);
  if (rc != 0) return error_from_errno(err, "fsync " + path.string());
  return Status::ok();
}

int write_all(int fd, const void* data, size_t size) {
  const auto* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (n == 0) return ENOSPC;
    p += n;
    size -= static_cast<size_t>(n);
  }
  return 0;
}

fs::path temporary_sibling(const fs::path& path) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  // Built with append: GCC 12 warns falsely (-Wrestrict) on chained operator+ here.
  std::string name = ".";
  name.append(path.filename().string()).append(".tmp").append(std::to_string(rng() % 1000000000));
  return path.parent_path() / name;
}

Status check_replaceable(const fs::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || S_ISREG(st.st_mode)) return Status::ok();  // absent, or a file to replace
  if (S_ISLNK(st.st_mode))
    return make_error(ErrorCode::kInvalidArgument,
                      path.string() + " is a symbolic link: not replaced (nor written through); remove it first");
  return make_error(ErrorCode::kInvalidArgument,
                    path.string() +
                        " exists and is not a regular file (a device, FIFO, socket or folder): not "
                        "replaced; write to a file instead");
}

Status check_no_symlinks_below(const fs::path& base, const fs::path& target) {
  const fs::path relative = target.lexically_relative(base);
  if (relative.empty() || *relative.begin() == "..")
    return make_error(ErrorCode::kInvalidArgument, target.string() + " is not inside " + base.string());
  fs::path walked = base;
  for (const auto& part : relative) {
    if (part == ".") continue;
    walked /= part;
    struct stat st {};
    if (::lstat(walked.c_str(), &st) != 0) {
      if (errno == ENOENT) return Status::ok();  // the rest is created by the writer
      return error_from_errno(errno, "lstat " + walked.string());
    }
    if (S_ISLNK(st.st_mode))
      return make_error(ErrorCode::kInvalidArgument, walked.string() + " is a symbolic link: refused (a link inside " +
                                                         base.string() + " could redirect the write; remove it)");
  }
  return Status::ok();
}

Result<int> create_new_file(const fs::path& path) {
  int fd = -1;
  do fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  while (fd < 0 && errno == EINTR);
  if (fd < 0) return error_from_errno(errno, "create " + path.string());
  return fd;
}

Status commit_temporary(const fs::path& temporary, const fs::path& path) {
  std::error_code ignored;
  if (auto s = check_replaceable(path); !s) {
    fs::remove(temporary, ignored);
    return s;
  }
  if (auto s = fsync_path(temporary, false); !s) {
    fs::remove(temporary, ignored);
    return s;
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const Error e = make_error(ErrorCode::kIo, "rename to " + path.string() + ": " + std::strerror(errno));
    fs::remove(temporary, ignored);
    return e;
  }
  const fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  return fsync_path(dir, true);
}

Status write_file_atomic(const fs::path& path, const std::string& bytes) {
  VDRIG_TRY(check_replaceable(path));
  const fs::path tmp = temporary_sibling(path);
  auto created = create_new_file(tmp);
  if (!created) return created.error();
  const int fd = created.value();
  if (const int err = write_all(fd, bytes.data(), bytes.size()); err != 0) {
    ::close(fd);
    std::error_code ignored;
    fs::remove(tmp, ignored);
    return error_from_errno(err, "write " + tmp.string());
  }
  ::close(fd);
  return commit_temporary(tmp, path);
}

}  // namespace vdrig

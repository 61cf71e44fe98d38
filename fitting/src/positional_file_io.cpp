#include "positional_file_io.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

#include "vdrig/core/file_write.hpp"

namespace vdrig::fitting {
namespace fs = std::filesystem;

namespace {

Error io_error(const std::string& what, const fs::path& path, int err) {
  return error_from_errno(err, what + " " + path.string());
}

/// The process's umask, read without changing it (umask(2) would race with other threads creating files).
mode_t process_umask() {
  std::FILE* f = std::fopen("/proc/self/status", "re");
  unsigned mask = 022;
  if (f) {
    char line[256];
    while (std::fgets(line, sizeof line, f))
      if (std::sscanf(line, "Umask: %o", &mask) == 1) break;
    std::fclose(f);
  }
  return static_cast<mode_t>(mask);
}

fs::path folder_of(const fs::path& path) { return path.parent_path().empty() ? fs::path(".") : path.parent_path(); }

}  // namespace

void UniqueFd::reset() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status write_at(int fd, const fs::path& path, const void* data, size_t n, uint64_t offset) {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, p, n, static_cast<off_t>(offset));
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error("writing", path, errno);
    }
    if (w == 0) return io_error("writing", path, ENOSPC);
    p += w;
    n -= static_cast<size_t>(w);
    offset += static_cast<uint64_t>(w);
  }
  return Status::ok();
}

Status read_at(int fd, const fs::path& path, void* data, size_t n, uint64_t offset) {
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (r < 0) {
      if (errno == EINTR) continue;
      return io_error("reading", path, errno);
    }
    if (r == 0)
      return make_error(ErrorCode::kCorrupt,
                        path.string() + " is truncated (ends before byte " + std::to_string(offset + n) + ")");
    p += r;
    n -= static_cast<size_t>(r);
    offset += static_cast<uint64_t>(r);
  }
  return Status::ok();
}

Result<UniqueFd> open_for_reading(const fs::path& path) {
  UniqueFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) {
    const int err = errno;
    return make_error(err == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo,
                      "opening " + path.string() + ": " + std::strerror(err));
  }
  return fd;
}

Result<UniqueFd> create_temporary_beside(const fs::path& path, fs::path* temporary) {
  const fs::path dir = folder_of(path);
  std::string tmpl = (dir / (path.filename().string() + ".tmp-XXXXXX")).string();
  UniqueFd fd(::mkstemp(tmpl.data()));
  if (fd.get() < 0) return io_error("creating a temporary file in", dir, errno);
  // mkstemp creates 0600; the finished file gets the mode of vdrig's other outputs (0666 less the umask).
  if (::fchmod(fd.get(), 0666 & ~process_umask()) != 0) {
    const Error e = io_error("setting the mode of", tmpl, errno);
    ::unlink(tmpl.c_str());
    return e;
  }
  *temporary = tmpl;
  return fd;
}

Result<UniqueFd> create_anonymous_file(const fs::path& dir, fs::path* name) {
  std::string tmpl = (dir / ".vdrig-obsmap-spill-XXXXXX").string();
  UniqueFd fd(::mkstemp(tmpl.data()));
  if (fd.get() < 0) return io_error("creating a spill file in", dir, errno);
  ::unlink(tmpl.c_str());
  *name = tmpl;
  return fd;
}

}  // namespace vdrig::fitting

#include "vdrig/core/file_read.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "vdrig/core/json_text.hpp"

namespace vdrig {
namespace fs = std::filesystem;

namespace {

/// What a non-regular file is, for messages.
const char* kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  return "not a regular file";
}

Status check_mode(const fs::path& path, mode_t mode) {
  if (S_ISREG(mode)) return Status::ok();
  return make_error(ErrorCode::kInvalidArgument, path.string() + " is " + kind_of(mode) + ", not a regular file");
}

}  // namespace

Status check_regular_file(const fs::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR) return make_error(ErrorCode::kNotFound, "no such file " + path.string());
    return make_error(ErrorCode::kIo, "stat " + path.string() + ": " + std::strerror(errno));
  }
  return check_mode(path, st.st_mode);
}

Result<std::string> read_regular_file(const fs::path& path, std::size_t max_bytes) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer before fstat could refuse it.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT || errno == ENOTDIR) return make_error(ErrorCode::kNotFound, "no such file " + path.string());
    return make_error(ErrorCode::kIo, "open " + path.string() + ": " + std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const Error e = make_error(ErrorCode::kIo, "stat " + path.string() + ": " + std::strerror(errno));
    ::close(fd);
    return e;
  }
  if (auto s = check_mode(path, st.st_mode); !s) {
    ::close(fd);
    return s.error();
  }
  if (static_cast<std::size_t>(st.st_size) > max_bytes) {
    ::close(fd);
    return make_error(ErrorCode::kInvalidArgument, path.string() + " is " + std::to_string(st.st_size) +
                                                       " bytes; at most " + std::to_string(max_bytes) + " are read");
  }
  std::string bytes(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const Error e = make_error(ErrorCode::kIo, "read " + path.string() + ": " + std::strerror(errno));
      ::close(fd);
      return e;
    }
    if (n == 0) break;  // shrank while reading: what was there is what is parsed
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  bytes.resize(done);
  return bytes;
}

Result<nlohmann::json> read_json_file(const fs::path& path) {
  auto bytes = read_regular_file(path, kMaxJsonFileBytes);
  if (!bytes) return bytes.error();
  auto j = parse_json_strict(bytes.value(), path.string());
  if (!j) return j.error();
  if (!j->is_object())
    return make_error(ErrorCode::kCorrupt,
                      path.string() + ": expected a JSON object at the top level, found " + j->type_name());
  return j;
}

}  // namespace vdrig

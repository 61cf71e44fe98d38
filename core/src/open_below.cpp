#include "vdrig/core/open_below.hpp"

#include <fcntl.h>
#include <unistd.h>

namespace vdrig {

int open_regular_below(const std::filesystem::path& dir, const std::vector<std::string>& parts, struct stat& st) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  for (std::size_t i = 0; i < parts.size() && fd >= 0; ++i) {
    const int flags = O_RDONLY | O_NOFOLLOW | O_CLOEXEC | (i + 1 < parts.size() ? O_DIRECTORY : 0);
    const int next = ::openat(fd, parts[i].c_str(), flags);
    ::close(fd);
    fd = next;
  }
  if (fd >= 0 && ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) return fd;
  if (fd >= 0) ::close(fd);
  return -1;
}

}  // namespace vdrig

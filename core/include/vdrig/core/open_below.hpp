// Opening a file below a folder without following links: one path component at a time (openat with O_NOFOLLOW), so
// that a symbolic link anywhere below the folder, or the folder itself being one, is refused rather than followed. For
// files a request names (the web console's session files), where a link planted in a session must not lead out of it.
#pragma once

#include <sys/stat.h>

#include <filesystem>
#include <string>
#include <vector>

namespace vdrig {

/// `dir`/parts[0]/.../parts[n-1], opened read-only one component at a time with O_NOFOLLOW (`dir` too) and fstat'ed
/// into `st`: its descriptor, which the caller closes. -1 (nothing left open) when a component is a link, missing or
/// unreadable, when one before the last is not a folder, or when the last is not a regular file.
int open_regular_below(const std::filesystem::path& dir, const std::vector<std::string>& parts, struct stat& st);

}  // namespace vdrig

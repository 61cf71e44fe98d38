// What every fuzz target shares: a private scratch folder (in /dev/shm when there is one: parsers that take a path
// are fed through a file, and a RAM disk keeps that cheap) and quiet logs (a warning per input would be most of the
// run's time).
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "vdrig/core/log.hpp"

namespace vdrig::fuzz {

/// A folder only this process uses, created on first call and removed at exit.
inline const std::filesystem::path& scratch_dir() {
  struct Dir {
    std::filesystem::path path;
    Dir() {
      (void)log::set_level("off");  // a known level: cannot fail
      const std::filesystem::path shm = "/dev/shm";
      std::error_code ec;
      const std::filesystem::path base = std::filesystem::is_directory(shm, ec) && ::access("/dev/shm", W_OK) == 0
                                             ? shm
                                             : std::filesystem::temp_directory_path();
      path = base / ("vdrig_fuzz_" + std::to_string(::getpid()));
      std::filesystem::remove_all(path, ec);
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

/// Replaces `path` with the bytes.
inline void write_bytes(const std::filesystem::path& path, const uint8_t* data, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
}

inline std::string as_string(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace vdrig::fuzz

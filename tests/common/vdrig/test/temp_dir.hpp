// Temporary folders for tests, the same in every module's tests.
//
// CTest runs each test case in a process of its own (gtest_discover_tests), and tests run in parallel (-j2), so a
// folder is named after the test's own `name` and the process id: <system temp dir>/vdrig_<name>_<pid>. Whatever
// an earlier, crashed run left under that name is removed first.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace vdrig::test {

/// An empty folder <system temp dir>/vdrig_<name>_<pid>, created (after removing what was there). The caller removes
/// it; prefer TempDir, which does so even when an ASSERT returns early.
inline std::filesystem::path fresh_temp_dir(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("vdrig_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// fresh_temp_dir(name), removed with everything in it when the object goes out of scope. Converts to the folder's
/// path, so `TempDir dir("x"); Session::create(dir / "s", ...)` and `write(dir, ...)` read as with a path.
class TempDir {
 public:
  explicit TempDir(const std::string& name) : path_(fresh_temp_dir(name)) {}
  ~TempDir() {
    std::error_code ignored;  // a destructor must not throw; a folder a test removed itself is fine
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  operator const std::filesystem::path&() const { return path_; }  // NOLINT(google-explicit-constructor)
  std::filesystem::path operator/(const std::filesystem::path& p) const { return path_ / p; }

 private:
  std::filesystem::path path_;
};

}  // namespace vdrig::test

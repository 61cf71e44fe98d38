// Every input fuzz/fuzz_parameter_map kept in fuzz/regressions/parameter_map/ reads to a value or an error (e.g. an
// EXR whose unknown attribute claims 1.9 GB: OpenEXR allocates it, read_exr reports the short read as kCorrupt).
#include <gtest/gtest.h>

#include <filesystem>

#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::fitting {
namespace {
namespace fs = std::filesystem;

TEST(ParameterMapFuzzRegressions, ReadToAValueOrAnError) {
  const fs::path folder = fs::path(VDRIG_SOURCE_DIR) / "fuzz" / "regressions" / "parameter_map";
  if (!fs::is_directory(folder)) GTEST_SKIP() << "no " << folder;
  for (const auto& entry : fs::directory_iterator(folder)) {
    Result<ParameterMap> map = Error{ErrorCode::kInternal, "not run"};
    EXPECT_NO_THROW(map = ParameterMap::read(entry.path())) << entry.path();
    if (!map) {
      EXPECT_NE(map.error().code, ErrorCode::kInternal) << entry.path();
    }
  }
}

}  // namespace
}  // namespace vdrig::fitting

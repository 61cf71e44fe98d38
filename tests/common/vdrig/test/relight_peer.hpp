// Where the relight-cli peer is (CNR-ISTI's RTI fitter, built from its source by scripts/build_relight), for the RTI
// tests that meet it. `./vdrig.sh test` builds it whenever its source is beside the repository and then sets
// VDRIG_REQUIRE_RELIGHT=1: a test that finds no peer fails there instead of skipping, so that a broken peer build
// cannot turn those tests green. Elsewhere (a clone with nothing beside it) they skip, naming what they looked for.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "vdrig/test/build_paths.hpp"

namespace vdrig::test {

/// $VDRIG_RELIGHT_CLI when set, else the link scripts/build_relight leaves in the source tree.
inline std::filesystem::path relight_cli_path() {
  if (const char* env = std::getenv("VDRIG_RELIGHT_CLI"); env && *env) return env;
  return std::filesystem::path(VDRIG_SOURCE_DIR) / "build/peers/relight/build/relight-cli/relight-cli";
}

/// True when relight_cli_path() is an executable file.
inline bool have_relight_cli() { return ::access(relight_cli_path().c_str(), X_OK) == 0; }

/// True when the run requires the peer (VDRIG_REQUIRE_RELIGHT=1, set by ./vdrig.sh test when it built it).
inline bool relight_required() {
  const char* value = std::getenv("VDRIG_REQUIRE_RELIGHT");
  return value != nullptr && std::string_view(value) == "1";
}

}  // namespace vdrig::test

/// In a test body or SetUp: skips the test (or fails it, where the peer is required) when relight-cli is absent.
#define VDRIG_REQUIRE_RELIGHT_CLI()                                                                              \
  do {                                                                                                           \
    if (!::vdrig::test::have_relight_cli()) {                                                                    \
      if (::vdrig::test::relight_required())                                                                     \
        GTEST_FAIL() << "relight-cli is required (VDRIG_REQUIRE_RELIGHT=1) and absent: "                         \
                     << ::vdrig::test::relight_cli_path();                                                       \
      GTEST_SKIP() << "relight-cli (the peer) is not built: run scripts/build_relight or set VDRIG_RELIGHT_CLI " \
                      "(looked for "                                                                             \
                   << ::vdrig::test::relight_cli_path() << ")";                                                  \
    }                                                                                                            \
  } while (false)

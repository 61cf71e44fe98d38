// Issue #27: the README's step-by-step block ("The same pipeline step by step") is run from its own text, so a
// renamed flag, a changed default or a step that no longer follows from the one before fails here instead of on a
// new user's first afternoon. Every `vdrig` line of the block runs, in order, in one folder, against the simulator,
// with only its sizes made smaller (kShrink: each replacement must still match, so the table cannot go stale); the
// lines that cannot run here are listed with the reason (kNotRunHere: each must still match a line of the block).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace {
namespace fs = std::filesystem;

/// Text replaced in the README's commands before they run: only sizes, so the step runs in seconds. Each `from` must
/// occur in the block.
struct Shrink {
  const char* from;
  const char* to;
};
constexpr Shrink kShrink[] = {
    {"512x512", "32x32"},  // the observation map, its file and the fits: 32x32 texels
    {"--scheme icosahedron:3@85", "--scheme icosahedron:2@85"},  // fewer views, still enough for hsh:6 and phong:auto
    {"--texel 100,200", "--texel 10,20"},                        // a texel inside the 32x32 map
    {"--scheme adaptive:60,", "--scheme adaptive:16,"},          // a base of 8 views and one or two batches
};

/// Lines of the block that do not run here, by the start of their command, with the reason. Each must match a line.
struct NotRun {
  const char* prefix;
  const char* reason;
};
constexpr NotRun kNotRunHere[] = {
    {"vdrig rig check my_rig.json", "needs the user's rig config (rig check runs in capture_test_rig_cli)"},
    {"vdrig capture --out S2 --rig my_rig.json", "needs the user's rig config"},
    {"vdrig view ", "an interactive window (the viewer's tests render the same maps headless)"},
    {"vdrig serve ", "a web server that runs until stopped (web_test_serve_cli and web_test_browser run it)"},
    {"mpirun ", "a cluster (cluster_test_mpi_fit runs vdrig fit --mpi under mpirun)"},
};

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  const auto last = s.find_last_not_of(" \t");
  return s.substr(first, last - first + 1);
}

/// The commands of the README's step-by-step block: each line that is not a comment, without its trailing comment.
std::vector<std::string> readme_steps(const std::string& readme) {
  const auto heading = readme.find("The same pipeline step by step");
  if (heading == std::string::npos) return {};
  const auto open = readme.find("```sh\n", heading);
  if (open == std::string::npos) return {};
  const auto body = open + 6;
  const auto close = readme.find("\n```", body);
  if (close == std::string::npos) return {};
  std::vector<std::string> commands;
  std::istringstream lines(readme.substr(body, close - body));
  for (std::string line; std::getline(lines, line);) {
    line = trim(line);
    if (line.empty() || line[0] == '#') continue;
    // A comment starts at " #" (no command of the block has a '#' of its own).
    const auto comment = line.find(" #");
    commands.push_back(trim(comment == std::string::npos ? line : line.substr(0, comment)));
  }
  return commands;
}

bool starts_with(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

TEST(ReadmeSteps, EveryStepOfTheBlockRunsOnTheSimulatorInOrder) {
  const std::string readme = read_text(fs::path(VDRIG_SOURCE_DIR) / "README.md");
  const auto steps = readme_steps(readme);
  ASSERT_GE(steps.size(), 15u) << "the README's step-by-step block was not found or lost most of its lines";

  std::string block;
  for (const auto& s : steps) block += s + "\n";
  for (const auto& shrink : kShrink) {
    EXPECT_NE(block.find(shrink.from), std::string::npos)
        << "kShrink is stale: \"" << shrink.from << "\" is no longer in the README's block";
  }
  for (const auto& not_run : kNotRunHere) {
    bool matched = false;
    for (const auto& s : steps) matched = matched || starts_with(s, not_run.prefix);
    EXPECT_TRUE(matched) << "kNotRunHere is stale: no line of the block starts with \"" << not_run.prefix << "\"";
  }

  const fs::path dir = vdrig::test::fresh_temp_dir("readme_steps");
  int ran = 0;
  for (std::string step : steps) {
    bool skip = false;
    for (const auto& not_run : kNotRunHere) skip = skip || starts_with(step, not_run.prefix);
    if (skip) continue;
    ASSERT_TRUE(starts_with(step, "vdrig ")) << "a line of the block that is neither vdrig nor listed: " << step;
    for (const auto& shrink : kShrink) {
      for (auto at = step.find(shrink.from); at != std::string::npos; at = step.find(shrink.from, at + 1)) {
        step.replace(at, std::string(shrink.from).size(), shrink.to);
      }
    }
    const std::string command = "cd " + vdrig::test::shell_quote(dir.string()) + " && " +
                                vdrig::test::shell_quote(VDRIG_CLI_PATH) + step.substr(5);
    const auto run = vdrig::test::run_shell(command, {120, true});
    ASSERT_EQ(run.exit_code, 0) << "README step failed: " << step << "\n" << run.out;
    std::printf("%6.1f s  %s\n", run.wall_s, step.c_str());
    ++ran;
  }
  EXPECT_GE(ran, 12) << "most of the block did not run";

  // What the block says the steps leave behind (after the shrink: 32x32 texels).
  for (const char* made : {"B/manifest.json", "camera.yml", "S/manifest.json", "S/calib/response.json",
                           "S/hdr/view_0000.exr", "S/calib/views.json", "S/obsmap/32x32.vdobs", "S/maps/phong:auto.exr",
                           "S/maps/hsh:6.exr", "texel.png", "v40.exr", "orbit.png", "err.exr", "report.html"}) {
    EXPECT_TRUE(fs::exists(dir / made)) << made << " was not written by the README's steps";
  }
  fs::remove_all(dir);
}

}  // namespace

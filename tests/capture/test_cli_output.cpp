// The CLI around a capture: `vdrig demo --out D` never deletes what it did not create (a non-empty D/session is
// refused and left as it was, unless it is an earlier demo's session holding only what the demo writes), and progress
// written to something that is not a terminal is plain newline-ended log lines at a modest rate, never '\r' redraws.
#include <gtest/gtest.h>

#include <algorithm>

#include "test_support.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;

TEST(CliDemo, RefusesANonEmptySessionFolderAndDeletesNothing) {
  vdrig::test::TempDir root("demo_out");
  const fs::path session = root.path() / "session";
  fs::create_directories(session / "calib");
  testing::write_text(session / "notes.txt", "my notes\n");
  testing::write_text(session / "calib" / "response.json", "{}\n");
  const auto r =
      testing::run_process({testing::vdrig_cli(), "demo", "--out", root.path().string(), "--scheme", "latlong:2",
                            "--chessboard-scheme", "latlong:2:65", "--res", "4x4", "--holdout", "1"});
  EXPECT_NE(r.exit_code, 0) << r.out << r.err;
  EXPECT_TRUE(fs::exists(session / "notes.txt")) << "the demo deleted a user's file";
  EXPECT_TRUE(fs::exists(session / "calib" / "response.json")) << "the demo deleted a user's file";
  EXPECT_NE(r.err.find("is not empty"), std::string::npos) << "stderr: " << r.err;
  EXPECT_NE(r.err.find("--out"), std::string::npos) << "stderr: " << r.err;
}

TEST(CliDemo, RunsAgainOverItsOwnSessionButNeverOverAUsersFile) {
  vdrig::test::TempDir root("demo_again");
  const fs::path session = root.path() / "session";
  // A 17-view chessboard session (latlong:2:65) instead of the demo's 56: quick, also under ASan.
  const std::vector<std::string> demo = {
      testing::vdrig_cli(), "demo",  "--out", root.path().string(), "--scheme", "latlong:2", "--chessboard-scheme",
      "latlong:2:65",       "--res", "4x4",   "--holdout",          "1"};
  const auto first = testing::run_process(demo, {600.0});
  ASSERT_EQ(first.exit_code, 0) << first.out << first.err;
  // The demo calibrates from the images (chessboard intrinsics, response, markers) and says which files it used.
  EXPECT_NE(first.out.find("calibration (from the images"), std::string::npos) << first.out;
  for (const fs::path& file : {root.path() / "chessboard" / "calib" / "camera.yml", session / "calib" / "response.json",
                               session / "calib" / "views.json", session / "calib" / "camera.yml"})
    EXPECT_TRUE(fs::exists(file)) << file;
  // What `vdrig compare` writes into the session by default (renders/compare/) is the demo's too.
  const auto compared = testing::run_process(
      {testing::vdrig_cli(), "compare", session.string(), "--maps", "phong:1", "--views", "held-out"}, {600.0});
  ASSERT_EQ(compared.exit_code, 0) << compared.out << compared.err;
  EXPECT_TRUE(fs::exists(session / "renders" / "compare" / "compare.json"));
  const auto again = testing::run_process(demo, {600.0});  // the README's `./vdrig.sh demo`, run a second time
  ASSERT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_TRUE(fs::exists(session / "maps" / "phong:1.exr"));
  // A user's file beside the demo's own makes the demo refuse, and nothing is deleted.
  testing::write_text(session / "maps" / "notes.txt", "my notes\n");
  const auto refused = testing::run_process(demo, {600.0});
  EXPECT_NE(refused.exit_code, 0) << refused.out << refused.err;
  EXPECT_NE(refused.err.find("notes.txt"), std::string::npos) << "stderr: " << refused.err;
  EXPECT_TRUE(fs::exists(session / "maps" / "notes.txt"));
  EXPECT_TRUE(fs::exists(session / "maps" / "phong:1.exr"));
  EXPECT_TRUE(fs::exists(session / "manifest.json"));
}

TEST(CliProgress, NotATerminalGetsNewlineEndedLinesWithoutCarriageReturns) {
  vdrig::test::TempDir root("progress");
  fs::create_directories(root.path());
  const fs::path rig_file = root.path() / "rig.json";
  testing::write_text(rig_file, testing::small_sim_config().dump(2));
  const auto r = testing::run_process({testing::vdrig_cli(), "capture", "--rig", rig_file.string(), "--scheme",
                                       "latlong:6", "--bracket", "fixed:0.01,0.005", "--out",
                                       (root.path() / "S").string(), "--reserve-mb", "0"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(r.out.find('\r'), std::string::npos) << "stdout holds '\\r' redraws: " << r.out.substr(0, 300);
  size_t longest = 0, lines = 0;
  for (size_t pos = 0; pos < r.out.size();) {
    const size_t end = std::min(r.out.find('\n', pos), r.out.size());
    longest = std::max(longest, end - pos);
    ++lines;
    pos = end + 1;
  }
  EXPECT_LT(longest, 200u) << r.out;
  EXPECT_LE(lines, 20u) << "progress is not at a modest rate:\n" << r.out;
  EXPECT_NE(r.out.find("100 %"), std::string::npos) << "no final progress line:\n" << r.out;
}

}  // namespace
}  // namespace vdrig::capture

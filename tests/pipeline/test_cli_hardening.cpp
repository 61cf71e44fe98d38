// Issue #18, process level: the built `vdrig` and `vdrigd` refuse bad input with a clear message and exit 1 or 2
// (never an abort, a hang or a silent exit 0), and leave nothing behind. VDRIG_CLI_UNDER_TEST / VDRIGD_UNDER_TEST
// in the environment run the checks against other binaries (e.g. a build from before the fixes).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "small_session.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

std::string binary(const char* env, const char* built) {
  const char* e = std::getenv(env);
  return e && *e ? e : built;
}

using vdrig::test::ProcessRun;

class CliHardening : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dir_ = vdrig::test::fresh_temp_dir("cli_hardening"); }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  /// Runs `program args` (a shell fragment) under a 60 s timeout with umask 022, capturing stdout and stderr.
  static ProcessRun run(const std::string& program, const std::string& args) {
    return vdrig::test::run_shell("umask 022; " + vdrig::test::shell_quote(program) + " " + args, {60});
  }
  static ProcessRun vdrig(const std::string& args) { return run(binary("VDRIG_CLI_UNDER_TEST", VDRIG_CLI_PATH), args); }
  static ProcessRun vdrigd(const std::string& args) {
    return run(binary("VDRIGD_UNDER_TEST", VDRIG_VDRIGD_PATH), args);
  }

  /// A small simulated session with its HDR views merged, built once (in process) for the tests that need one.
  static const fs::path& session() {
    static const fs::path dir = [] {
      const fs::path out = dir_ / "session";
      auto s = test::small_merged_session(out);
      EXPECT_TRUE(s) << s.error().describe();
      return out;
    }();
    return dir;
  }

  static fs::path dir_;
};
fs::path CliHardening::dir_;

/// A clear refusal: exit 1 or 2 (not a signal, a hang or success) with `needle` on stderr.
void expect_refused(const ProcessRun& r, const std::string& needle, int code = 0) {
  EXPECT_TRUE(r.exit_code == 1 || r.exit_code == 2) << "exit " << r.exit_code << "\nstderr: " << r.err;
  if (code != 0) {
    EXPECT_EQ(r.exit_code, code) << r.err;
  }
  EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr lacks \"" << needle << "\": " << r.err;
}

// --- item 1: JSON inputs that are directories -------------------------------------------------------------------

TEST_F(CliHardening, JsonInputsThatAreDirectoriesAreRefused) {
  const fs::path d = dir_ / "a_dir.json";
  fs::create_directories(d);
  expect_refused(vdrig("capture --rig '" + d.string() + "' --out '" + (dir_ / "never").string() + "'"),
                 "is a directory", 2);
  EXPECT_FALSE(fs::exists(dir_ / "never"));
  expect_refused(vdrig("hdr merge --response '" + d.string() + "' x.png:0.1 --out '" + (dir_ / "m.exr").string() + "'"),
                 "is a directory");
  expect_refused(vdrigd("--sessions-dir '" + (dir_ / "sessions").string() + "' --runtime-dir '" +
                        (dir_ / "run").string() + "' --rig '" + d.string() + "'"),
                 "is a directory", 2);
  // A session whose manifest.json is a directory.
  const fs::path s = dir_ / "dir_manifest";
  fs::create_directories(s / "manifest.json");
  std::ofstream(s / "journal.jsonl") << "";
  expect_refused(vdrig("hdr '" + s.string() + "'"), "is a directory");
}

TEST_F(CliHardening, SessionCalibrationFileThatIsADirectoryIsRefused) {
  // calib/views.json (and calib/response.json) as directories, in a copy of the session.
  const fs::path s = dir_ / "dir_views";
  fs::copy(session(), s, fs::copy_options::recursive);
  fs::remove(s / "calib" / "views.json");
  fs::remove(s / "calib" / "camera.yml");
  fs::create_directories(s / "calib" / "views.json");
  fs::create_directories(s / "calib" / "camera.yml");
  expect_refused(vdrig("obsmap build '" + s.string() + "' --res 8x8"), "is a directory");
  const fs::path r = dir_ / "dir_response";
  fs::copy(session(), r, fs::copy_options::recursive);
  fs::remove_all(r / "hdr");
  fs::remove(r / "calib" / "response.json");
  fs::create_directories(r / "calib" / "response.json");
  expect_refused(vdrig("hdr '" + r.string() + "'"), "is a directory");
}

TEST_F(CliHardening, FifoFrameIsRefusedNotWaitedOn) {
  const fs::path s = dir_ / "fifo_frame";
  fs::copy(session(), s, fs::copy_options::recursive);
  auto opened = capture::Session::open(s);
  ASSERT_TRUE(opened) << opened.error().describe();
  const auto frames = opened->frames_of_view(opened->manifest().views.front().index);
  ASSERT_FALSE(frames.empty());
  fs::remove(s / frames.front().file);
  ASSERT_EQ(::mkfifo((s / frames.front().file).c_str(), 0600), 0);
  fs::remove_all(s / "hdr");
  expect_refused(vdrig("hdr '" + s.string() + "'"), "is a FIFO");  // timed out (124) before
  const std::string fifo = "'" + (s / frames.front().file).string() + "'";
  expect_refused(
      vdrig("calib intrinsics " + fifo + " " + fifo + " " + fifo + " --out '" + (dir_ / "c.yml").string() + "'"),
      "is a FIFO");
}

// --- item 2: arguments that aborted -----------------------------------------------------------------------------

TEST_F(CliHardening, FuseHeightBeyondTheLimitIsAUsageError) {
  // A real (16 x 8 lat-long) probe, so that only the height can stop the fusion.
  ExrImage probe;
  for (const char* c : {"R", "G", "B"}) probe.add(c, cv::Mat(8, 16, CV_32FC1, cv::Scalar::all(1.0)));
  const fs::path file = dir_ / "probe.exr";
  ASSERT_TRUE(write_exr(file, probe));
  expect_refused(vdrig("probe fuse '" + file.string() +
                       ":0,0,0' --room -1000,-1000,-1000,1000,1000,1000 --at 10,0,0 --height 100000 --out '" +
                       (dir_ / "fused.exr").string() + "'"),
                 "fusion height", 2);
}

TEST_F(CliHardening, IntrinsicsRefuseTinyImagesAndHugeSubpixelWindows) {
  const fs::path tiny = dir_ / "tiny.png";
  ASSERT_TRUE(write_png(tiny, cv::Mat(2, 2, CV_8UC1, cv::Scalar::all(128))));
  const std::string three = "'" + tiny.string() + "' '" + tiny.string() + "' '" + tiny.string() + "'";
  expect_refused(vdrig("calib intrinsics " + three + " --out '" + (dir_ / "cam.yml").string() + "'"), "px a side", 2);
  const fs::path grey = dir_ / "grey.png";
  ASSERT_TRUE(write_png(grey, cv::Mat(480, 640, CV_8UC1, cv::Scalar::all(128))));
  const std::string greys = "'" + grey.string() + "' '" + grey.string() + "' '" + grey.string() + "'";
  expect_refused(
      vdrig("calib intrinsics " + greys + " --subpix-half-window 100000 --out '" + (dir_ / "cam.yml").string() + "'"),
      "half window", 2);
}

TEST_F(CliHardening, FitThreadsBeyondTheLimitIsRefusedBeforeAnyWork) {
  const ProcessRun r = vdrig("fit '" + session().string() + "' --res 8x8 --threads 100000");
  expect_refused(r, "threads", 2);
  EXPECT_EQ(r.out.find("observation map"), std::string::npos) << r.out;
}

TEST_F(CliHardening, HugeSimulatedCameraIsRefusedBeforeTheSessionFolderExists) {
  auto rc = sim::sim_rig_config({{"camera", {{"width", 100000}, {"height", 100000}}}});
  const fs::path rig = dir_ / "huge_camera.json";
  std::ofstream(rig) << rc.dump();
  const fs::path out = dir_ / "huge_session";
  expect_refused(vdrig("capture --rig '" + rig.string() + "' --scheme latlong:1 --out '" + out.string() + "'"), "4096",
                 2);
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(CliHardening, AdaptiveCaptureWithoutIntrinsicsIsRefusedBeforeTheSessionFolderExists) {
  // The planner projects with the camera's intrinsics: without camera=FILE.yml a new session has none, and the
  // capture used to stop only after its base views.
  const fs::path out = dir_ / "adaptive_session";
  expect_refused(vdrig("capture --scheme adaptive:16 --out '" + out.string() + "'"), "camera=FILE.yml");
  EXPECT_FALSE(fs::exists(out));
  expect_refused(vdrig("capture --scheme adaptive:16,camera=/nonexistent.yml --out '" + out.string() + "'"),
                 "/nonexistent.yml");
  EXPECT_FALSE(fs::exists(out));
}

// --- item 3: settings that silently disabled a check --------------------------------------------------------------

TEST_F(CliHardening, ReserveMbMustBeANonNegativeNumber) {
  for (const char* bad : {"nan", "-1"}) {
    const fs::path out = dir_ / (std::string("reserve_") + bad);
    expect_refused(vdrig(std::string("capture --rig sim --scheme latlong:1 --reserve-mb=") + bad + " --out '" +
                         out.string() + "'"),
                   "--reserve-mb", 2);
    EXPECT_FALSE(fs::exists(out)) << bad;
  }
  expect_refused(vdrigd("--sessions-dir '" + (dir_ / "sessions").string() + "' --runtime-dir '" +
                        (dir_ / "run").string() + "' --reserve-mb=-1"),
                 "--reserve-mb", 2);
}

TEST_F(CliHardening, UnknownLogLevelIsRefusedWithTheValidLevels) {
  expect_refused(vdrig("--log-level bogus hdr '" + (dir_ / "nowhere").string() + "'"), "trace, debug, info", 2);
  expect_refused(vdrigd("--log-level bogus --sessions-dir '" + (dir_ / "sessions").string() + "'"),
                 "trace, debug, info", 2);
}

// --- item 4 ------------------------------------------------------------------------------------------------------

TEST_F(CliHardening, HdrMergesDamagedViewsAgainAndForceMergesEveryView) {
  const fs::path s = dir_ / "damaged_hdr";
  fs::copy(session(), s, fs::copy_options::recursive);
  auto opened = capture::Session::open(s);
  ASSERT_TRUE(opened);
  const auto layout = opened->layout();
  const int damaged = opened->manifest().views.at(1).index, intact = opened->manifest().views.at(0).index;
  fs::resize_file(layout.hdr_file(damaged), fs::file_size(layout.hdr_file(damaged)) / 2);
  ASSERT_FALSE(read_exr(layout.hdr_file(damaged)));
  const auto intact_time = fs::last_write_time(layout.hdr_file(intact));

  ProcessRun r = vdrig("hdr '" + s.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(read_exr(layout.hdr_file(damaged))) << "the truncated view was skipped";
  EXPECT_EQ(fs::last_write_time(layout.hdr_file(intact)), intact_time) << "an intact view was merged again";

  r = vdrig("hdr --force '" + s.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GT(fs::last_write_time(layout.hdr_file(intact)), intact_time) << "--force left an intact view";
}

TEST_F(CliHardening, FitChecksTheOutputFolderBeforeFitting) {
  const fs::path file = dir_ / "a_file";
  std::ofstream(file) << "x";
  const ProcessRun r = vdrig("fit '" + session().string() + "' --res 8x8 --out '" + (file / "map.exr").string() + "'");
  expect_refused(r, "--out");
  EXPECT_EQ(r.out.find("observation map"), std::string::npos) << "refused only after the work:\n" << r.out;
}

// Before: `fit --res 8192x8192` fitted for hours and wrote a map that `render` then refused ("needs 4352 MiB").
TEST_F(CliHardening, FitRefusesAMapThatCouldNotBeReadBackBeforeFitting) {
  const ProcessRun r = vdrig("fit '" + session().string() + "' --model phong:1 --res 8192x8192");
  expect_refused(r, "can read back", 2);
  EXPECT_EQ(r.out.find("observation map"), std::string::npos) << "refused only after the work:\n" << r.out;
  // A map that reads back is fitted as before.
  EXPECT_EQ(vdrig("fit '" + session().string() + "' --model phong:1 --res 8x8").exit_code, 0);
}

// Issue #27: a mistyped flag gets the nearest flag of the subcommand it was given to; a flag far from every valid one
// gets no guess.
TEST_F(CliHardening, AMistypedFlagGetsTheNearestFlag) {
  const std::string s = "'" + session().string() + "'";
  ProcessRun r = vdrig("fit " + s + " --modle phong:1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--modle: did you mean --model?"), std::string::npos) << r.err;
  r = vdrig("compare " + s + " --maps phong:1 --veiws 1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--veiws: did you mean --views?"), std::string::npos) << r.err;
  r = vdrig("fit " + s + " --res=8x8 --smoothnig=1e-4");  // --name=value too
  EXPECT_NE(r.err.find("--smoothnig: did you mean --smoothing?"), std::string::npos) << r.err;
  r = vdrig("fit " + s + " --zqxwv 1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err.find("did you mean"), std::string::npos) << r.err;
}

TEST_F(CliHardening, FitHelpListsEveryModelForm) {
  const ProcessRun r = vdrig("fit --help");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  for (const char* form : {"phong:K", "phong:K:per-lobe-m", "phong:auto", "phong:auto:per-lobe-m"})
    EXPECT_NE(r.out.find(form), std::string::npos) << form << " missing from:\n" << r.out;
}

// A fit that fails (here: no HDR views to build the observation map from) leaves no empty maps/ or obsmap/ folder.
TEST_F(CliHardening, AFailedFitLeavesNoEmptyFolders) {
  const fs::path s = dir_ / "no_hdr";
  fs::copy(session(), s, fs::copy_options::recursive);
  fs::remove_all(s / "hdr");
  fs::remove_all(s / "maps");
  fs::remove_all(s / "obsmap");
  const ProcessRun r = vdrig("fit '" + s.string() + "' --model phong:1 --res 8x8");
  EXPECT_NE(r.exit_code, 0) << r.out;
  EXPECT_FALSE(fs::exists(s / "maps")) << "an empty maps/ was left behind";
  EXPECT_FALSE(fs::exists(s / "obsmap")) << "an empty obsmap/ was left behind";
}

TEST_F(CliHardening, ObservationMapFilesGetTheModeOfOtherOutputs) {
  const fs::path file = dir_ / "mode.vdobs";
  const ProcessRun r = vdrig("obsmap build '" + session().string() + "' --res 8x8 --out '" + file.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  struct stat st {};
  ASSERT_EQ(::stat(file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0644u) << std::oct << (st.st_mode & 0777);  // umask 022 in run()
}

}  // namespace
}  // namespace vdrig::pipeline

// `vdrig rti import|fit|export` as a user runs them: the thin commands over rti/ and fitting/, their exit codes
// and messages.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "synthetic_stack.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

using test::ProcessRun;

/// `vdrig args` with stdout and stderr together in `out` (the tests look for messages of either).
ProcessRun vdrig(const std::string& args) { return test::run_vdrig(args, {.timeout_s = 120, .merge_stderr = true}); }

// Issue #25: OpenCV's imgcodecs (Debian's links GDAL, GDCM, HDF5, Poppler...) cost every vdrig process ~0.15 s CPU
// and 50 MB before main, more than a small stack's whole fit. Images go through libpng and libjpeg instead; neither
// vdrig nor vdrigd may load imgcodecs, highgui, videoio or GDAL, directly or through another library.
TEST(RtiCli, ExecutablesLoadNoOpenCvImgcodecs) {
  for (const std::string& exe : {std::string(VDRIG_CLI_PATH), std::string(VDRIG_VDRIGD_PATH)}) {
    const ProcessRun ldd = test::run_process({"/usr/bin/ldd", exe});
    ASSERT_EQ(ldd.exit_code, 0) << ldd.out << ldd.err;
    EXPECT_NE(ldd.out.find("libopencv_core"), std::string::npos) << ldd.out;  // ldd did list the libraries
    EXPECT_NE(ldd.out.find("libpng16"), std::string::npos) << ldd.out;
    EXPECT_NE(ldd.out.find("libjpeg"), std::string::npos) << ldd.out;
    for (const char* banned : {"libopencv_imgcodecs", "libopencv_highgui", "libopencv_videoio", "libgdal"})
      EXPECT_EQ(ldd.out.find(banned), std::string::npos) << exe << " loads " << banned;
  }
}

// Issue #25: `vdrig rti` runs as the thin vdrig-rti beside vdrig (apps/vdrig/main.cpp), which maps none of the
// libraries only other subcommands need (their shared pages were most of a small fit's peak memory).
TEST(RtiCli, ThinExecutableLinksOnlyWhatRtiNeedsAndHasVdrigsHelp) {
  const std::string front = VDRIG_CLI_PATH;
  const std::string thin = (std::filesystem::path(front).parent_path() / "vdrig-rti").string();
  const ProcessRun ldd = test::run_process({"/usr/bin/ldd", thin});
  ASSERT_EQ(ldd.exit_code, 0) << ldd.out << ldd.err;
  EXPECT_NE(ldd.out.find("libopencv_core"), std::string::npos) << ldd.out;  // ldd did list the libraries
  for (const char* banned : {"libcamera", "libmpi", "libssl", "libcrypto", "libGL.so", "libglfw", "libmodbus",
                             "libgpiod", "libusb", "libopencv_calib3d", "libopencv_imgcodecs"})
    EXPECT_EQ(ldd.out.find(banned), std::string::npos) << "vdrig-rti loads " << banned;
  // Typed by hand `vdrig-rti fit ...` is `vdrig rti fit ...`: the same help, errors and exit codes (but for the
  // program's name CLI11 prints).
  const auto as_front = [&](std::string text) {
    for (size_t at = text.find(thin + " rti"); at != std::string::npos; at = text.find(thin + " rti"))
      text.replace(at, thin.size(), front);
    return text;
  };
  const std::vector<std::pair<std::vector<std::string>, std::vector<std::string>>> cases{
      {{front, "rti", "--help"}, {thin, "--help"}},
      {{front, "rti", "fit", "--help"}, {thin, "fit", "--help"}},
      {{front, "rti", "fit"}, {thin, "fit"}},  // required arguments missing
      {{front, "--log-level", "warn", "rti", "export", "m.exr", "--fromat", "ptm"},
       {thin, "--log-level", "warn", "export", "m.exr", "--fromat", "ptm"}}};  // a typo, with its suggestion
  for (const auto& [via_front, direct] : cases) {
    const ProcessRun a = test::run_process(via_front), b = test::run_process(direct);
    EXPECT_EQ(a.exit_code, b.exit_code) << via_front.back();
    EXPECT_EQ(a.out, as_front(b.out)) << via_front.back();
    EXPECT_EQ(a.err, as_front(b.err)) << via_front.back();
    EXPECT_EQ(a.exit_code == 0, via_front.back() == "--help") << a.out << a.err;
  }
}

// vdrig execs the vdrig-rti beside it with its own argv and exit code, and runs the command itself without one.
TEST(RtiCli, FrontExecsTheThinExecutableOrRunsRtiItself) {
  test::TempDir dir("rti_cli_thin");
  const std::filesystem::path front = dir / "vdrig", thin = dir / "vdrig-rti";
  std::filesystem::copy_file(VDRIG_CLI_PATH, front);
  std::filesystem::permissions(front, std::filesystem::perms::owner_all);
  {
    std::ofstream script(thin);
    script << "#!/bin/sh\necho \"thin: $*\"\nexit 7\n";
  }
  std::filesystem::permissions(thin, std::filesystem::perms::owner_all);
  ProcessRun r = test::run_process({front.string(), "--log-level", "warn", "rti", "fit", "--help"});
  EXPECT_EQ(r.exit_code, 7) << r.out << r.err;
  EXPECT_EQ(r.out, "thin: --log-level warn rti fit --help\n");
  r = test::run_process({front.string(), "--help"});  // other commands, and vdrig's own help, stay in vdrig
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("Subcommands:"), std::string::npos) << r.out;
  std::filesystem::remove(thin);
  r = test::run_process({front.string(), "rti", "fit", "--help"});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find(front.string() + " rti fit [OPTIONS] input"), std::string::npos) << r.out;
}

TEST(RtiCli, ImportFitExport) {
  test::TempDir dir("rti_cli");
  std::filesystem::create_directories(dir / "stack");
  test::write_synthetic_stack(dir / "stack", 16, 12, 30, ".jpg");
  const std::string d = dir.path().string();
  ProcessRun r = vdrig("rti import " + d + "/stack --out " + d + "/s.vdobs --response linear --crop 2,2,10,8");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("30 images of 10x8"), std::string::npos) << r.out;
  r = vdrig("rti fit " + d + "/s.vdobs --model hsh:3 --out " + d + "/m.exr");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("median leave-one-out RMS"), std::string::npos) << r.out;
  for (const char* format : {"rti", "relight"}) {
    r = vdrig("rti export " + d + "/m.exr --format " + format + " --out " + d + "/out." + format);
    EXPECT_EQ(r.exit_code, 0) << r.out;
  }
  EXPECT_TRUE(std::filesystem::exists(dir / "out.relight" / "info.json"));
  // A fitted file made elsewhere comes back as a parameter map that view, render and compare take.
  for (const char* fitted : {"out.rti", "out.relight"}) {
    r = vdrig("rti import " + d + "/" + fitted + " --out " + d + "/back.exr");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("(hsh:3, 10x8 texels)"), std::string::npos) << r.out;
  }
  r = vdrig("rti import " + d + "/out.rti --out " + d + "/back.vdobs");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("a fitted file is imported as a parameter map (.exr)"), std::string::npos) << r.out;
  // A model the format cannot hold: refused with the reason.
  r = vdrig("rti export " + d + "/m.exr --format ptm --out " + d + "/out.ptm");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find(".ptm needs a ptm:rgb or ptm:lrgb map"), std::string::npos) << r.out;
}

TEST(RtiCli, BadInputsAreRefusedWithTheReason) {
  test::TempDir dir("rti_cli_bad");
  const std::string d = dir.path().string();
  std::ofstream(dir / "a.lp") << "2\nimg.jpg 0 0 1\n";
  ProcessRun r = vdrig("rti import " + d + "/a.lp --out " + d + "/s.vdobs");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("count line says 2, the file lists 1 images"), std::string::npos) << r.out;
  r = vdrig("rti import " + d + "/a.lp --out " + d + "/s.vdobs --crop 1,2,3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("--crop must be x,y,w,h"), std::string::npos) << r.out;
  r = vdrig("rti export " + d + "/none.exr --format png --out " + d + "/x");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("expected ptm, rti or relight"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace vdrig::rti

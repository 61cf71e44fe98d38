// `vdrig rti import|fit|export` as a user runs them: the thin commands over rti/ and fitting/, their exit codes
// and messages.
#include <gtest/gtest.h>

#include <cstdlib>

#include "synthetic_stack.hpp"
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

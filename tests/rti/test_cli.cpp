// `vdrig rti import|fit|export` as a user runs them: the thin commands over rti/ and fitting/, their exit codes
// and messages.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "synthetic_stack.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

struct Cli {
  int exit_code = -1;
  std::string output;
};

Cli vdrig(const test::TempDir& dir, const std::string& args) {
  const std::string log = (dir / "cli.log").string();
  const int status = std::system((std::string(VDRIG_CLI_PATH) + " " + args + " > " + log + " 2>&1").c_str());
  std::ifstream in(log);
  std::ostringstream s;
  s << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, s.str()};
}

TEST(RtiCli, ImportFitExport) {
  test::TempDir dir("rti_cli");
  std::filesystem::create_directories(dir / "stack");
  test::write_synthetic_stack(dir / "stack", 16, 12, 30, ".jpg");
  const std::string d = dir.path().string();
  Cli r = vdrig(dir, "rti import " + d + "/stack --out " + d + "/s.vdobs --response linear --crop 2,2,10,8");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("30 images of 10x8"), std::string::npos) << r.output;
  r = vdrig(dir, "rti fit " + d + "/s.vdobs --model hsh:3 --out " + d + "/m.exr");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("median leave-one-out RMS"), std::string::npos) << r.output;
  for (const char* format : {"rti", "relight"}) {
    r = vdrig(dir, "rti export " + d + "/m.exr --format " + format + " --out " + d + "/out." + format);
    EXPECT_EQ(r.exit_code, 0) << r.output;
  }
  EXPECT_TRUE(std::filesystem::exists(dir / "out.relight" / "info.json"));
  // A model the format cannot hold: refused with the reason.
  r = vdrig(dir, "rti export " + d + "/m.exr --format ptm --out " + d + "/out.ptm");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find(".ptm needs a ptm:rgb or ptm:lrgb map"), std::string::npos) << r.output;
}

TEST(RtiCli, BadInputsAreRefusedWithTheReason) {
  test::TempDir dir("rti_cli_bad");
  const std::string d = dir.path().string();
  std::ofstream(dir / "a.lp") << "2\nimg.jpg 0 0 1\n";
  Cli r = vdrig(dir, "rti import " + d + "/a.lp --out " + d + "/s.vdobs");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("count line says 2, the file lists 1 images"), std::string::npos) << r.output;
  r = vdrig(dir, "rti import " + d + "/a.lp --out " + d + "/s.vdobs --crop 1,2,3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--crop must be x,y,w,h"), std::string::npos) << r.output;
  r = vdrig(dir, "rti export " + d + "/none.exr --format png --out " + d + "/x");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("expected ptm, rti or relight"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace vdrig::rti

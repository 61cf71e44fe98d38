// `vdrig rti rbf` as a user runs it: the command over rti/pca_basis.hpp, its output, exit codes and messages.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "synthetic_stack.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

using test::ProcessRun;

ProcessRun vdrig(const std::string& args) { return test::run_vdrig(args, {.timeout_s = 120, .merge_stderr = true}); }

TEST(RtiRbfCli, ImportThenRbf) {
  test::TempDir dir("rti_rbf_cli");
  std::filesystem::create_directories(dir / "stack");
  test::write_synthetic_stack(dir / "stack", 24, 16, 40, ".jpg");
  const std::string d = dir.path().string();
  ProcessRun r = vdrig("rti import " + d + "/stack --out " + d + "/s.vdobs --response linear");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = vdrig("rti rbf " + d + "/s.vdobs --out " + d + "/web --planes 6 --hold-out 3,17");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("rbf over mrgb, 6 planes, 38 lights, 24x16 texels"), std::string::npos) << r.out;
  std::ifstream in(dir / "web" / "info.json");
  const auto info = nlohmann::json::parse(in);
  EXPECT_EQ(info["type"], "rbf");
  EXPECT_EQ(info["nplanes"], 6);
  EXPECT_EQ(info["lights"].size(), 3u * 38);
  EXPECT_TRUE(std::filesystem::exists(dir / "web" / "plane_1.jpg"));
  EXPECT_FALSE(std::filesystem::exists(dir / "web" / "plane_2.jpg"));

  // Refusals name the reason and exit with the usage code.
  r = vdrig("rti rbf " + d + "/s.vdobs --out " + d + "/bad --planes 8");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("a multiple of 3"), std::string::npos) << r.out;
  r = vdrig("rti rbf " + d + "/s.vdobs --out " + d + "/bad --hold-out 3,x");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("\"x\" is not a view index"), std::string::npos) << r.out;
  r = vdrig("rti rbf " + d + "/s.vdobs --out " + d + "/bad --encoding gamma");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("expected codes"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad"));
  r = vdrig("rti rbf " + d + "/missing.vdobs --out " + d + "/bad");
  EXPECT_NE(r.exit_code, 0) << r.out;

  // Straight from the stack (its folder or its .lp), as `vdrig rti fit STACK`: no observation map on disk.
  r = vdrig("rti rbf " + d + "/stack --out " + d + "/direct --planes 6 --hold-out 3,17");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("rbf over mrgb, 6 planes, 38 lights, 24x16 texels"), std::string::npos) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir / "direct" / "plane_1.jpg"));
  r = vdrig("rti rbf " + d + "/stack/stack.lp --out " + d + "/bad --encoding srgb");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("photographs hold the codes"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad"));
}

}  // namespace
}  // namespace vdrig::rti

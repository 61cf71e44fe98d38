// The atomic writers (write_file_atomic, write_exr, write_png) refuse a symbolic link at their target instead of
// silently replacing it: whoever planted it meant the write to land elsewhere.
#include <gtest/gtest.h>

#include <fstream>

#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {
namespace fs = std::filesystem;

TEST(AtomicWriteLinks, ALinkAtTheTargetIsRefusedAndKept) {
  vdrig::test::TempDir dir("atomic_links");
  const fs::path victim = dir.path() / "victim";
  { std::ofstream(victim) << "precious"; }
  ExrImage exr;
  exr.add("Y", cv::Mat(2, 2, CV_32FC1, cv::Scalar(1.0f)));
  const fs::path json_link = dir.path() / "out.json", exr_link = dir.path() / "out.exr",
                 png_link = dir.path() / "out.png";
  for (const fs::path& link : {json_link, exr_link, png_link}) fs::create_symlink(victim, link);

  const Status json_written = write_file_atomic(json_link, "{}\n");
  const Status exr_written = write_exr(exr_link, exr, ExrPixelType::kFloat);
  const Status png_written = write_png(png_link, cv::Mat(2, 2, CV_8UC1, cv::Scalar(7)));
  for (const Status* s : {&json_written, &exr_written, &png_written}) {
    ASSERT_FALSE(*s);
    EXPECT_NE(s->error().message.find("symbolic link"), std::string::npos) << s->error().message;
  }
  for (const fs::path& link : {json_link, exr_link, png_link}) EXPECT_TRUE(fs::is_symlink(link)) << link;
  std::ifstream in(victim);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "precious");
  // No temporary is left beside them.
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++entries;
  EXPECT_EQ(entries, 4);
}

}  // namespace
}  // namespace vdrig

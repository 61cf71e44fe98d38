// ExrImage::add_bgr, the one conversion of OpenCV's B, G, R images into OpenEXR's R, G, B channels: the file is read
// back with OpenEXR's own API (not vdrig's reader, which could share a mistake), channel by channel.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "vdrig/core/image_io.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {

/// Channel `name` of the EXR file at `path` as float, read by OpenEXR.
cv::Mat read_channel(const std::string& path, const char* name) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i dw = file.header().dataWindow();
  const int width = dw.max.x - dw.min.x + 1, height = dw.max.y - dw.min.y + 1;
  cv::Mat plane(height, width, CV_32FC1, cv::Scalar(-12345));
  if (!file.header().channels().findChannel(name)) return {};
  Imf::FrameBuffer fb;
  char* origin = reinterpret_cast<char*>(plane.ptr<float>()) -
                 (static_cast<ptrdiff_t>(dw.min.x) + static_cast<ptrdiff_t>(dw.min.y) * width) * sizeof(float);
  fb.insert(name, Imf::Slice(Imf::FLOAT, origin, sizeof(float), sizeof(float) * width));
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return plane;
}

TEST(ExrBgr, ThirdPlaneIsRedFirstIsBlue) {
  const test::TempDir dir("exr_bgr");
  // Every plane differs from the others at every pixel, and varies across the image, so a swap or a transposition
  // shows: B = x + 0.25, G = 100 + y, R = -1000 - x * y (exact in float, as OpenEXR's FLOAT channels keep them).
  constexpr int kWidth = 7, kHeight = 5;
  cv::Mat bgr(kHeight, kWidth, CV_32FC3);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
      bgr.at<cv::Vec3f>(y, x) = cv::Vec3f(x + 0.25f, 100.0f + y, -1000.0f - static_cast<float>(x * y));
  ExrImage exr;
  exr.add_bgr(bgr);
  const std::string file = (dir / "bgr.exr").string();
  ASSERT_TRUE(write_exr(file, exr).is_ok());

  const Imf::InputFile in(file.c_str());
  std::vector<std::string> names;
  for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) names.push_back(c.name());
  EXPECT_EQ(names, (std::vector<std::string>{"B", "G", "R"}));  // OpenEXR lists channels sorted by name
  cv::Mat planes[3];
  cv::split(bgr, planes);
  const struct {
    const char* name;
    int plane;
  } expected[] = {{"R", 2}, {"G", 1}, {"B", 0}};
  for (const auto& [name, plane] : expected) {
    const cv::Mat read = read_channel(file, name);
    ASSERT_EQ(read.size(), bgr.size()) << name;
    EXPECT_EQ(cv::norm(read, planes[plane], cv::NORM_INF), 0.0) << "channel " << name << " is not plane " << plane;
  }
}

TEST(ExrBgrDeathTest, NeedsThreeFloatPlanes) {
  ExrImage exr;
  EXPECT_DEATH(exr.add_bgr(cv::Mat(2, 2, CV_8UC3)), "CV_32FC3");
  EXPECT_DEATH(exr.add_bgr(cv::Mat(2, 2, CV_32FC1)), "CV_32FC3");
}

}  // namespace
}  // namespace vdrig

// The console's frame thumbnail (web/src/thumbnail.cpp): size, tone curve and the saturated fraction of known frames.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "../../web/src/thumbnail.hpp"
#include "vdrig/core/image_codec.hpp"

namespace vdrig::web {
namespace {

TEST(WebThumbnail, Base64MatchesTheStandardAlphabetAndPadding) {
  EXPECT_EQ(base64(""), "");
  EXPECT_EQ(base64("f"), "Zg==");
  EXPECT_EQ(base64("fo"), "Zm8=");
  EXPECT_EQ(base64("foo"), "Zm9v");
  EXPECT_EQ(base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(base64(std::string("\xff\xfe\x00", 3)), "//4A");
}

TEST(WebThumbnail, A16BitFrameIsBoxFilteredToneMappedAndItsSaturationCounted) {
  // 960x480, 16-bit BGR: the left half at 18% of full scale, the right half's top quarter saturated in one channel.
  cv::Mat frame(480, 960, CV_16UC3, cv::Scalar::all(0.18 * 65535));
  frame(cv::Rect(480, 0, 480, 120)).setTo(cv::Scalar(65535, 0.18 * 65535, 0.18 * 65535));
  frame(cv::Rect(480, 120, 480, 360)).setTo(cv::Scalar::all(0));
  auto png = encode_png(frame);
  ASSERT_TRUE(png);
  auto t = frame_thumbnail(png.value(), "frame.png", 240);
  ASSERT_TRUE(t) << t.error().describe();
  EXPECT_EQ(t->value("width", 0), 960);
  EXPECT_EQ(t->value("bits", 0), 16);
  EXPECT_EQ(t->value("thumb_width", 0), 240);
  EXPECT_EQ(t->value("thumb_height", 0), 120);
  EXPECT_DOUBLE_EQ(t->value("saturated_fraction", -1.0), 480.0 * 120 / (960.0 * 480));
  const std::string b64 = t->value("png_base64", "");
  // Decode the thumbnail back (base64 by hand: the test's own, independent of base64()).
  std::string bytes;
  int bits = 0, acc = 0;
  for (const char ch : b64) {
    const auto at = std::string("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/").find(ch);
    if (at == std::string::npos) break;
    acc = (acc << 6) | static_cast<int>(at), bits += 6;
    if (bits >= 8) bits -= 8, bytes += static_cast<char>((acc >> bits) & 255);
  }
  auto thumb = decode_image(bytes, "thumb.png");
  ASSERT_TRUE(thumb) << thumb.error().describe();
  ASSERT_EQ(thumb->cols, 240);
  ASSERT_EQ(thumb->type(), CV_8UC3);
  // 18% grey is sRGB 118 (0.18 -> 0.4613); black stays 0; the saturated blue channel is 255.
  EXPECT_NEAR(thumb->at<cv::Vec3b>(60, 60)[1], 118, 1);
  EXPECT_EQ(thumb->at<cv::Vec3b>(100, 200)[0], 0);
  EXPECT_EQ(thumb->at<cv::Vec3b>(10, 200)[0], 255);
}

TEST(WebThumbnail, BytesThatAreNotAnImageAreCorruptNamingTheFrame) {
  auto t = frame_thumbnail("not a png", "frames/view_0001_e00.png", 240);
  ASSERT_FALSE(t);
  EXPECT_EQ(t.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(t.error().message.find("view_0001_e00"), std::string::npos);
}

}  // namespace
}  // namespace vdrig::web

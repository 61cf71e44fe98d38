// PNG, JPEG and TIFF through libpng, libjpeg and libtiff (core/src/image_codec.cpp), checked against OpenCV's
// imgcodecs as an independent peer: what vdrig writes OpenCV reads back exactly, what OpenCV writes vdrig decodes to
// the same pixels OpenCV's own decoder gives (IMREAD_UNCHANGED and IMREAD_COLOR, whose layouts callers expect: BGR
// order, depth kept), and a damaged file is an error naming it, never an abort or a grey-filled image.
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {

namespace fs = std::filesystem;

/// A pattern with every channel different (a swapped R and B shows) and values over the whole range of the depth.
cv::Mat pattern(int rows, int cols, int type) {
  cv::Mat m(rows, cols, type);
  const int channels = m.channels();
  const double top = m.depth() == CV_16U ? 65535.0 : 255.0;
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      for (int c = 0; c < channels; ++c) {
        const double v = std::fmod(x * 37.0 + y * 101.0 + c * 53.0 + x * y * 0.7, top + 1.0);
        if (m.depth() == CV_16U)
          m.ptr<uint16_t>(y)[x * channels + c] = static_cast<uint16_t>(v * 257.0 > top ? v : v * 257.0);
        else
          m.ptr<uint8_t>(y)[x * channels + c] = static_cast<uint8_t>(v);
      }
  return m;
}

std::string bytes_of(const std::vector<uchar>& v) { return std::string(v.begin(), v.end()); }

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

double max_diff(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return 1e9;
  return cv::norm(a, b, cv::NORM_INF);
}

TEST(ImageCodec, WhatVdrigWritesOpenCvReadsExactly) {
  test::TempDir dir("image_codec_write");
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3, CV_16UC4}) {
    const cv::Mat image = pattern(37, 53, type);
    const fs::path file = dir / ("t" + std::to_string(type) + ".png");
    ASSERT_TRUE(write_png(file, image));
    const cv::Mat peer = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(max_diff(peer, image), 0.0) << "type " << type;
    auto back = read_png(file);
    ASSERT_TRUE(back) << back.error().describe();
    EXPECT_EQ(max_diff(back.value(), image), 0.0) << "type " << type;
    for (const PngCompression c : {PngCompression::kFastest, PngCompression::kSmaller}) {
      auto encoded = encode_png(image, c);
      ASSERT_TRUE(encoded);
      const std::vector<uchar> v(encoded->begin(), encoded->end());
      EXPECT_EQ(max_diff(cv::imdecode(v, cv::IMREAD_UNCHANGED), image), 0.0) << "type " << type;
    }
  }
  // A non-continuous view (a crop) is written as what it shows.
  const cv::Mat big = pattern(40, 60, CV_8UC3);
  const cv::Mat crop = big(cv::Rect(5, 7, 20, 11));
  ASSERT_TRUE(write_png(dir / "crop.png", crop));
  EXPECT_EQ(max_diff(cv::imread((dir / "crop.png").string(), cv::IMREAD_UNCHANGED), crop), 0.0);
  // JPEG (the report's inline images): OpenCV decodes it to what its own encoder's file decodes to, within the
  // codes two encoders of the same libjpeg defaults may differ by.
  for (const int type : {CV_8UC1, CV_8UC3}) {
    const cv::Mat image = pattern(33, 47, type);
    auto jpeg = encode_jpeg(image, 90);
    ASSERT_TRUE(jpeg) << jpeg.error().describe();
    std::vector<uchar> peer;
    ASSERT_TRUE(cv::imencode(".jpg", image, peer, {cv::IMWRITE_JPEG_QUALITY, 90}));
    const cv::Mat ours = cv::imdecode(std::vector<uchar>(jpeg->begin(), jpeg->end()), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(ours.type(), type);
    EXPECT_LE(max_diff(ours, cv::imdecode(peer, cv::IMREAD_UNCHANGED)), 2.0) << "type " << type;
  }
  EXPECT_FALSE(encode_jpeg(cv::Mat(4, 4, CV_16UC3), 90));
  EXPECT_FALSE(encode_jpeg(cv::Mat(4, 4, CV_8UC3), 0));
  EXPECT_FALSE(encode_png(cv::Mat(4, 4, CV_32FC1)));
  EXPECT_FALSE(encode_png(cv::Mat(4, 4, CV_8UC2)));
}

TEST(ImageCodec, WhatOpenCvWritesVdrigDecodesAsOpenCvDoes) {
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3, CV_16UC4}) {
    std::vector<uchar> png;
    ASSERT_TRUE(cv::imencode(".png", pattern(29, 31, type), png));
    for (const auto& [mode, flag] :
         {std::pair{ImageDecode::kUnchanged, cv::IMREAD_UNCHANGED}, std::pair{ImageDecode::kBgr8, cv::IMREAD_COLOR}}) {
      auto ours = decode_image(bytes_of(png), "p.png", mode);
      ASSERT_TRUE(ours) << ours.error().describe();
      const cv::Mat peer = cv::imdecode(png, flag);
      EXPECT_EQ(ours->type(), peer.type()) << "type " << type << " flag " << flag;
      EXPECT_EQ(max_diff(ours.value(), peer), 0.0) << "type " << type << " flag " << flag;
    }
  }
  // TIFF (what RTI stacks and still cameras may hold): the strips as they are, LZW-compressed (OpenCV's default).
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3, CV_16UC4}) {
    std::vector<uchar> tiff;
    ASSERT_TRUE(cv::imencode(".tif", pattern(29, 31, type), tiff));
    for (const auto& [mode, flag] :
         {std::pair{ImageDecode::kUnchanged, cv::IMREAD_UNCHANGED}, std::pair{ImageDecode::kBgr8, cv::IMREAD_COLOR}}) {
      auto ours = decode_image(bytes_of(tiff), "p.tif", mode);
      ASSERT_TRUE(ours) << ours.error().describe();
      const cv::Mat peer = cv::imdecode(tiff, flag);
      EXPECT_EQ(ours->type(), peer.type()) << "type " << type << " flag " << flag;
      // 16-bit colour to 8 bits: OpenCV rounds where vdrig keeps the high byte (as OpenCV's PNG path does).
      EXPECT_LE(max_diff(ours.value(), peer), flag == cv::IMREAD_COLOR ? 1.0 : 0.0)
          << "type " << type << " flag " << flag;
    }
  }
  // JPEG, colour and grey, baseline and progressive: the same libjpeg-turbo underneath, so the same pixels.
  for (const int type : {CV_8UC1, CV_8UC3})
    for (const int progressive : {0, 1}) {
      std::vector<uchar> jpeg;
      ASSERT_TRUE(cv::imencode(".jpg", pattern(45, 67, type), jpeg,
                               {cv::IMWRITE_JPEG_QUALITY, 90, cv::IMWRITE_JPEG_PROGRESSIVE, progressive}));
      for (const auto& [mode, flag] : {std::pair{ImageDecode::kUnchanged, cv::IMREAD_UNCHANGED},
                                       std::pair{ImageDecode::kBgr8, cv::IMREAD_COLOR}}) {
        auto ours = decode_image(bytes_of(jpeg), "p.jpg", mode);
        ASSERT_TRUE(ours) << ours.error().describe();
        const cv::Mat peer = cv::imdecode(jpeg, flag);
        EXPECT_EQ(ours->type(), peer.type()) << "type " << type << " flag " << flag;
        EXPECT_LE(max_diff(ours.value(), peer), 1.0) << "type " << type << " flag " << flag;
      }
    }
}

TEST(ImageCodec, DamagedFilesAreErrorsNamingThem) {
  test::TempDir dir("image_codec_damage");
  const cv::Mat image = pattern(64, 64, CV_8UC3);
  ASSERT_TRUE(write_png(dir / "whole.png", image));
  std::vector<uchar> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", image, jpeg));
  const std::string png = slurp(dir / "whole.png");
  const std::string jpg = bytes_of(jpeg);
  std::vector<uchar> tiff;
  ASSERT_TRUE(cv::imencode(".tif", image, tiff, {cv::IMWRITE_TIFF_COMPRESSION, 1}));  // uncompressed
  const std::string tif = bytes_of(tiff);
  struct Case {
    std::string name, bytes, says;
  };
  std::string flipped = png;
  flipped[png.size() / 2] ^= 0x55;  // inside the image data: zlib or the CRC catches it
  const std::vector<Case> cases = {
      {"cut.png", png.substr(0, png.size() / 2), "truncated"},
      {"header.png", png.substr(0, 20), "truncated"},
      {"flipped.png", flipped, "(PNG)"},
      {"cut.jpg", jpg.substr(0, jpg.size() / 2), "truncated"},
      {"header.jpg", jpg.substr(0, 40), "(JPEG)"},
      {"text.png", "not an image at all", "neither PNG, JPEG nor TIFF"},
      {"scan.tif", std::string("II*\0", 4) + std::string(100, '\0'), "(TIFF)"},
      {"cut.tif", tif.substr(0, tif.size() / 2), "(TIFF)"},
  };
  for (const Case& c : cases) {
    std::ofstream(dir / c.name, std::ios::binary) << c.bytes;
    auto r = read_png(dir / c.name);
    ASSERT_FALSE(r) << c.name;
    EXPECT_EQ(r.error().code, ErrorCode::kCorrupt) << c.name;
    EXPECT_NE(r.error().message.find((dir / c.name).string()), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find(c.says), std::string::npos) << r.error().message;
  }
  // A JPEG whose header claims a huge image is refused by its size before any pixel is allocated.
  std::string huge = jpg;
  const size_t sof = huge.find("\xFF\xC0");
  ASSERT_NE(sof, std::string::npos);
  huge[sof + 5] = huge[sof + 7] = static_cast<char>(0x4E);  // height and width 0x4E40 = 20032
  huge[sof + 6] = huge[sof + 8] = static_cast<char>(0x40);
  auto r = decode_image(huge, "huge.jpg");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message.find("20032x20032 JPEG"), std::string::npos) << r.error().message;
}

}  // namespace
}  // namespace vdrig

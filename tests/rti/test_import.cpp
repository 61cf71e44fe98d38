#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "synthetic_stack.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

ImportOptions linear_options() {
  ImportOptions o;
  o.linearisation.kind = Linearisation::Kind::kCodes;
  return o;
}

TEST(RtiImport, ObservationsArePixelsAndDirectionsAreTheLights) {
  test::TempDir dir("rti_import_values");
  const auto stack = test::write_synthetic_stack(dir.path(), 12, 8, 10);
  ImportOptions options = linear_options();
  options.file.tile_size = 5;    // edge tiles
  options.file.zstd_level = -5;  // zstd's fast levels, as vdrig rti import uses
  auto summary = import_stack(dir.path(), dir / "map.vdobs", options);
  ASSERT_TRUE(summary) << summary.error().describe();
  EXPECT_EQ(summary->images, 10);
  auto reader = fitting::ObsMapReader::open(dir / "map.vdobs");
  ASSERT_TRUE(reader);
  EXPECT_EQ(reader->spec().texels_s, 12);
  EXPECT_EQ(reader->spec().texels_t, 8);
  EXPECT_EQ(reader->views(), 10);
  auto map = reader->read_all();
  ASSERT_TRUE(map);
  for (int t : {0, 7})
    for (int s : {0, 11}) {
      const fitting::TexelObservations obs = map->texel(s, t);
      ASSERT_EQ(obs.size(), 10u);
      for (int v = 0; v < 10; ++v) {
        EXPECT_NEAR((obs.direction[v].cast<double>() - stack.lights[v]).norm(), 0.0, 1e-6);
        const Vec3d truth = stack.radiance(s, t, stack.lights[v]);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(obs.radiance[v][c], truth[c], 0.5 / 255 + 1e-6);
      }
    }
}

TEST(RtiImport, CropAndSrgbLinearisation) {
  test::TempDir dir("rti_import_crop");
  test::write_synthetic_stack(dir.path(), 12, 8, 6);
  ImportOptions o;
  o.linearisation.kind = Linearisation::Kind::kSrgb;
  o.crop = cv::Rect(2, 1, 5, 4);
  auto summary = import_stack(dir / "stack.lp", dir / "map.vdobs", o);
  ASSERT_TRUE(summary) << summary.error().describe();
  EXPECT_EQ(summary->width, 5);
  EXPECT_EQ(summary->height, 4);
  // Pixel (2 + s, 1 + row) of image 0, sRGB-decoded; texel t = 3 - row.
  const cv::Mat image = cv::imread((dir / "image_000.png").string());
  auto map = fitting::ObsMapReader::open(dir / "map.vdobs")->read_all();
  ASSERT_TRUE(map);
  Eigen::Vector3f rgb, d;
  map->observation(1, 3, 0, &rgb, &d);  // row 0 of the crop
  const double code = image.at<cv::Vec3b>(1, 3)[2] / 255.0;
  const double linear = code <= 0.04045 ? code / 12.92 : std::pow((code + 0.055) / 1.055, 2.4);
  EXPECT_NEAR(rgb[0], linear, 1e-6);

  o.crop = cv::Rect(10, 0, 5, 4);
  auto outside = import_stack(dir.path(), dir / "bad.vdobs", o);
  ASSERT_FALSE(outside);
  EXPECT_EQ(outside.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(outside.error().message.find("not inside the 12x8 images"), std::string::npos);
}

TEST(RtiImport, ErrorsNameTheImage) {
  test::TempDir dir("rti_import_errors");
  test::write_synthetic_stack(dir.path(), 12, 8, 4);
  std::filesystem::remove(dir / "image_002.png");
  auto missing = import_stack(dir.path(), dir / "map.vdobs", linear_options());
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("image 3 of"), std::string::npos) << missing.error().message;
  EXPECT_NE(missing.error().message.find("image_002.png"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "map.vdobs"));

  cv::imwrite((dir / "image_002.png").string(), cv::Mat(9, 12, CV_8UC3, cv::Scalar(10, 20, 30)));
  auto mixed = import_stack(dir.path(), dir / "map.vdobs", linear_options());
  ASSERT_FALSE(mixed);
  EXPECT_EQ(mixed.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(mixed.error().message.find("image 3 (" + (dir / "image_002.png").string() + ") is 12x9, the first is 12x8"),
            std::string::npos)
      << mixed.error().message;

  std::ofstream(dir / "image_002.png") << "not an image";
  auto broken = import_stack(dir.path(), dir / "map.vdobs", linear_options());
  ASSERT_FALSE(broken);
  EXPECT_NE(broken.error().message.find("image_002.png"), std::string::npos) << broken.error().message;
}

TEST(RtiImport, SixteenBitAndGreyImages) {
  test::TempDir dir("rti_import_16bit");
  cv::imwrite((dir / "a.png").string(), cv::Mat(4, 5, CV_16UC1, cv::Scalar(65535 / 2)));
  std::ofstream(dir / "s.lp") << "1\na.png 0 0 1\n";
  auto summary = import_stack(dir.path(), dir / "map.vdobs", linear_options());
  ASSERT_TRUE(summary) << summary.error().describe();
  auto map = fitting::ObsMapReader::open(dir / "map.vdobs")->read_all();
  Eigen::Vector3f rgb, d;
  map->observation(0, 0, 0, &rgb, &d);
  EXPECT_NEAR(rgb[2], 32767.0 / 65535.0, 1e-6);
}

TEST(RtiImport, ResponseNames) {
  EXPECT_EQ(Linearisation::parse("sRGB")->kind, Linearisation::Kind::kSrgb);
  EXPECT_EQ(Linearisation::parse("linear")->kind, Linearisation::Kind::kCodes);
  EXPECT_EQ(Linearisation::parse("codes")->kind, Linearisation::Kind::kCodes);
  EXPECT_EQ(Linearisation{}.kind, Linearisation::Kind::kCodes);  // what the viewers show (docs/rti.md, Colour)
  EXPECT_EQ(Linearisation::parse("/nonexistent/response.json").error().code, ErrorCode::kNotFound);
}

}  // namespace
}  // namespace vdrig::rti

#include <gtest/gtest.h>

#include <fstream>

#include "vdrig/rti/light_positions.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

std::string error_of(const std::string& text) {
  auto r = parse_light_positions(text, "/stack");
  EXPECT_FALSE(r);
  if (r) return "";
  EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
  return r.error().message;
}

TEST(LightPositions, ParsesAndNormalises) {
  auto r = parse_light_positions("2\r\nimg_1.jpg 0 0 2\n\n  my image 2.jpg  0.6 -0.0 0.8 \n", "/stack");
  ASSERT_TRUE(r) << r.error().describe();
  ASSERT_EQ(r->size(), 2u);
  EXPECT_EQ((*r)[0].image, std::filesystem::path("/stack/img_1.jpg"));
  EXPECT_NEAR(((*r)[0].direction - Vec3d(0, 0, 1)).norm(), 0.0, 1e-12);
  EXPECT_EQ((*r)[1].image, std::filesystem::path("/stack/my image 2.jpg"));  // names may hold spaces
  EXPECT_NEAR(((*r)[1].direction - Vec3d(0.6, 0, 0.8)).norm(), 0.0, 1e-12);
}

TEST(LightPositions, WindowsPathsResolveBesideTheLpFile) {
  test::TempDir dir("rti_lp_windows");
  std::ofstream(dir / "IMG_0001.JPG") << "x";
  auto r = parse_light_positions("1\nC:\\dome\\capture\\IMG_0001.JPG 0.1 0.2 0.9\n", dir.path());
  ASSERT_TRUE(r);
  EXPECT_EQ((*r)[0].image, dir / "IMG_0001.JPG");
}

TEST(LightPositions, ErrorsNameTheProblemAndTheLine) {
  EXPECT_NE(error_of("").find("empty"), std::string::npos);
  EXPECT_NE(error_of("two\na.jpg 0 0 1\n").find("line 1: the first line must be the image count"), std::string::npos);
  EXPECT_NE(error_of("3\na.jpg 0 0 1\nb.jpg 0 1 1\n").find("count line says 3, the file lists 2 images"),
            std::string::npos);
  EXPECT_NE(error_of("1\na.jpg 0 0 1\nb.jpg 0 1 1\n").find("count line says 1, the file lists 2"), std::string::npos);
  EXPECT_NE(error_of("2\na.jpg 0 0 1\nb.jpg 0 0 0\n").find("line 3: zero light direction"), std::string::npos);
  EXPECT_NE(error_of("1\na.jpg 0 1\n").find("line 2: expected \"FILENAME X Y Z\""), std::string::npos);
  EXPECT_NE(error_of("1\na.jpg 0 x 1\n").find("line 2: \"x\" is not a number"), std::string::npos);
  EXPECT_NE(error_of("1\na.jpg 0 nan 1\n").find("is not a number"), std::string::npos);
}

TEST(LightPositions, FindsTheSingleLpFileOfAFolder) {
  test::TempDir dir("rti_lp_find");
  EXPECT_EQ(find_light_positions(dir.path()).error().code, ErrorCode::kNotFound);
  std::ofstream(dir / "a.lp") << "1\na.jpg 0 0 1\n";
  auto one = find_light_positions(dir.path());
  ASSERT_TRUE(one);
  EXPECT_EQ(one.value(), dir / "a.lp");
  std::ofstream(dir / "b.lp") << "1\na.jpg 0 0 1\n";
  auto two = find_light_positions(dir.path());
  ASSERT_FALSE(two);
  EXPECT_EQ(two.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(two.error().message.find("several .lp files"), std::string::npos);
  EXPECT_EQ(read_light_positions(dir / "missing.lp").error().code, ErrorCode::kNotFound);
}

}  // namespace
}  // namespace vdrig::rti

// The one-pass stack fit (rti/stack_fit.hpp) gives the map of import + fit_parameter_map, channel for channel, for
// JPEG stacks (streamed through libjpeg) and PNG ones (decoded whole), with and without a crop; bad stacks get the
// reason, a corrupt JPEG included (libjpeg's default handler would end the process).
#include <gtest/gtest.h>

#include <fstream>

#include "synthetic_stack.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/rti/stack_fit.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;

fitting::ParameterMap fit_imported(const fs::path& stack, const fs::path& obsmap, const std::string& model,
                                   const std::optional<cv::Rect>& crop) {
  ImportOptions import;
  import.crop = crop;
  auto imported = import_stack(stack, obsmap, import);
  EXPECT_TRUE(imported) << imported.error().describe();
  auto reader = fitting::ObsMapReader::open(obsmap);
  EXPECT_TRUE(reader);
  fitting::MapFitOptions options;
  options.model = fitting::parse_model(model).value();
  options.threads = 2;
  auto map = fitting::fit_parameter_map(reader.value(), options);
  EXPECT_TRUE(map) << map.error().describe();
  return std::move(map.value());
}

/// Largest absolute difference over every channel of `a` that `b` has too; fails when a channel is missing.
double largest_difference(const fitting::ParameterMap& a, const fitting::ParameterMap& b) {
  double worst = 0;
  for (const std::string& channel : a.image().channel_names) {
    if (!b.has(channel)) {
      ADD_FAILURE() << "the stack fit has no channel " << channel;
      continue;
    }
    for (int t = 0; t < a.texels_t(); ++t)
      for (int s = 0; s < a.texels_s(); ++s)
        worst = std::max(worst, static_cast<double>(std::abs(a.at(channel, s, t) - b.at(channel, s, t))));
  }
  return worst;
}

TEST(StackFit, GivesTheMapOfImportAndFit) {
  struct Case {
    const char* ext;
    const char* model;
    std::optional<cv::Rect> crop;
  };
  for (const Case& c : {Case{".jpg", "hsh:3", std::nullopt}, Case{".jpg", "ptm:rgb", cv::Rect(3, 2, 21, 13)},
                        Case{".png", "hsh:2", cv::Rect(0, 4, 30, 10)}, Case{".png", "sh-ls:3", std::nullopt}}) {
    SCOPED_TRACE(std::string(c.ext) + " " + c.model);
    test::TempDir dir("rti_stack_fit");
    test::write_synthetic_stack(dir.path(), 30, 20, 40, c.ext);
    const fitting::ParameterMap imported = fit_imported(dir.path(), dir / "s.vdobs", c.model, c.crop);
    StackFitOptions options;
    options.model = fitting::parse_model(c.model).value();
    options.crop = c.crop;
    options.threads = 2;
    auto direct = fit_stack(dir.path(), options);
    ASSERT_TRUE(direct) << direct.error().describe();
    ASSERT_EQ(direct->texels_s(), imported.texels_s());
    ASSERT_EQ(direct->texels_t(), imported.texels_t());
    // Single against double precision on values of order 1 (mpe.* in percent, n an integer).
    EXPECT_LT(largest_difference(imported, direct.value()), 2e-4);
  }
}

TEST(StackFit, BadStacksGetTheReason) {
  test::TempDir dir("rti_stack_fit_bad");
  test::write_synthetic_stack(dir.path(), 16, 12, 20, ".jpg");
  StackFitOptions options;
  options.model = fitting::parse_model("hsh:3").value();
  // A truncated JPEG: an error naming the file, not libjpeg ending the process.
  fs::resize_file(dir / "image_007.jpg", fs::file_size(dir / "image_007.jpg") / 3);
  auto cut = fit_stack(dir.path(), options);
  ASSERT_FALSE(cut);
  EXPECT_EQ(cut.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(cut.error().message.find("image_007.jpg"), std::string::npos) << cut.error().message;
  // A missing image, before anything is decoded.
  fs::remove(dir / "image_011.jpg");
  auto missing = fit_stack(dir.path(), options);
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("image 12 of"), std::string::npos) << missing.error().message;
  // A crop outside the images; a model that is not one linear operator.
  test::TempDir good("rti_stack_fit_good");
  test::write_synthetic_stack(good.path(), 16, 12, 20, ".jpg");
  options.crop = cv::Rect(10, 0, 10, 5);
  auto outside = fit_stack(good.path(), options);
  ASSERT_FALSE(outside);
  EXPECT_NE(outside.error().message.find("is not inside the 16x12 images"), std::string::npos)
      << outside.error().message;
  options.crop.reset();
  options.model = fitting::parse_model("phong:1").value();
  auto phong = fit_stack(good.path(), options);
  ASSERT_FALSE(phong);
  EXPECT_NE(phong.error().message.find("vdrig rti import"), std::string::npos) << phong.error().message;
}

}  // namespace
}  // namespace vdrig::rti

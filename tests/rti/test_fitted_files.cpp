// Reading fitted RTI files back into parameter maps (rti/fitted_files.hpp). A round trip through vdrig's own writer
// proves only that the two halves agree; the layouts themselves are judged by the viewers (test_openlime.cpp) and by
// relight-cli (test_relight_peer.cpp). Here: every format and model round-trips within its quantisation, and bad
// files get a clear error.
#include <gtest/gtest.h>

#include <fstream>

#include "fit_support.hpp"
#include "synthetic_stack.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/rti/export.hpp"
#include "vdrig/rti/fitted_files.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;

class FittedFiles : public ::testing::Test {
 protected:
  static constexpr int kS = 18, kT = 12, kLights = 30;

  void SetUp() override {
    stack_ = test::write_synthetic_stack(dir_.path(), kS, kT, kLights);
    auto imported = import_stack(dir_.path(), dir_ / "map.vdobs");
    ASSERT_TRUE(imported) << imported.error().describe();
  }

  fitting::ParameterMap fit(const std::string& model) { return test::fit_imported_stack(dir_ / "map.vdobs", model); }

  /// Largest |read - original| in 8-bit codes over every texel at every light of the stack.
  double round_trip_error(const fitting::ParameterMap& original, const fitting::ParameterMap& read) {
    EXPECT_EQ(read.model().name(), original.model().name());
    EXPECT_EQ(read.texels_s(), kS);
    EXPECT_EQ(read.texels_t(), kT);
    double worst = 0;
    for (int t = 0; t < kT; ++t)
      for (int s = 0; s < kS; ++s)
        for (const Vec3d& l : stack_.lights)
          worst = std::max(worst, 255.0 * (read.evaluate(s, t, l) - original.evaluate(s, t, l)).cwiseAbs().maxCoeff());
    return worst;
  }

  test::TempDir dir_{"rti_fitted"};
  test::SyntheticStack stack_;
};

TEST_F(FittedFiles, EveryFormatRoundTripsWithinItsQuantisation) {
  struct Case {
    const char* model;
    ExportFormat format;
    const char* out;
    double max_codes;  // quantisation: half a step per coefficient summed over the terms; JPEG adds up to 2 codes
  };
  for (const Case& c :
       {Case{"ptm:rgb", ExportFormat::kPtm, "a.ptm", 1.5}, Case{"ptm:lrgb", ExportFormat::kPtm, "b.ptm", 2.0},
        Case{"hsh:2", ExportFormat::kRti, "c.rti", 1.5}, Case{"hsh:3", ExportFormat::kRti, "d.rti", 1.5},
        Case{"ptm:rgb", ExportFormat::kRelight, "e", 3.0}, Case{"hsh:3", ExportFormat::kRelight, "f", 3.0}}) {
    SCOPED_TRACE(std::string(c.model) + " -> " + c.out);
    const fitting::ParameterMap map = fit(c.model);
    ExportOptions options;
    options.jpeg_quality = 100;
    ASSERT_TRUE(export_map(map, c.format, dir_ / c.out, options));
    ASSERT_TRUE(is_fitted_file(dir_ / c.out));
    auto read = read_fitted_file(dir_ / c.out);
    ASSERT_TRUE(read) << read.error().describe();
    EXPECT_LT(round_trip_error(map, read.value()), c.max_codes);
  }
}

TEST_F(FittedFiles, BadFilesGetTheReason) {
  const fitting::ParameterMap map = fit("hsh:3");
  ASSERT_TRUE(export_map(map, ExportFormat::kRti, dir_ / "ok.rti"));
  // Truncated: the message says how many bytes there are and how many are needed.
  fs::copy_file(dir_ / "ok.rti", dir_ / "cut.rti");
  fs::resize_file(dir_ / "cut.rti", fs::file_size(dir_ / "ok.rti") - 100);
  auto cut = read_fitted_file(dir_ / "cut.rti");
  ASSERT_FALSE(cut);
  EXPECT_EQ(cut.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(cut.error().message.find("truncated"), std::string::npos) << cut.error().message;
  // A format named and refused.
  std::ofstream(dir_ / "jpeg.ptm") << "PTM_1.2\nPTM_FORMAT_JPEG_RGB\n4\n4\n";
  auto jpeg = read_fitted_file(dir_ / "jpeg.ptm");
  ASSERT_FALSE(jpeg);
  EXPECT_EQ(jpeg.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(jpeg.error().message.find("PTM_FORMAT_JPEG_RGB"), std::string::npos);
  std::ofstream(dir_ / "junk.ptm") << "hello";
  EXPECT_EQ(read_fitted_file(dir_ / "junk.ptm").error().code, ErrorCode::kCorrupt);
  // A relight folder without its planes, and one of a basis vdrig does not read.
  ASSERT_TRUE(export_map(map, ExportFormat::kRelight, dir_ / "web"));
  fs::remove(dir_ / "web" / "plane_4.jpg");
  auto missing = read_fitted_file(dir_ / "web");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("plane_4.jpg"), std::string::npos) << missing.error().message;
  fs::create_directories(dir_ / "bilinear");
  std::ofstream(dir_ / "bilinear" / "info.json")
      << R"({"width": 4, "height": 4, "type": "bilinear", "colorspace": "mrgb"})";
  auto bilinear = read_fitted_file(dir_ / "bilinear");
  ASSERT_FALSE(bilinear);
  EXPECT_EQ(bilinear.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(bilinear.error().message.find("\"bilinear\""), std::string::npos);
  // rbf folders are read (tests/rti/test_rbf.cpp); one without its lights, basis and planes is corrupt.
  fs::create_directories(dir_ / "rbf");
  std::ofstream(dir_ / "rbf" / "info.json") << R"({"width": 4, "height": 4, "type": "rbf", "colorspace": "mrgb"})";
  auto rbf = read_fitted_file(dir_ / "rbf");
  ASSERT_FALSE(rbf);
  EXPECT_EQ(rbf.error().code, ErrorCode::kCorrupt);
  EXPECT_FALSE(is_fitted_file(dir_ / "stack.lp"));
}

}  // namespace
}  // namespace vdrig::rti

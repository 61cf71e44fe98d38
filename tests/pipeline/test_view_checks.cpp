// Issue #18: HDR views are checked when the observation map reads them. A NaN or Inf pixel is masked (and counted)
// rather than turning every texel's fit into NaN; an HDR view of the wrong size is refused.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "small_session.hpp"
#include "vdrig/calib/hdr.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

class ViewChecks : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vdrig::test::fresh_temp_dir("view_checks");
    auto s = test::small_merged_session(dir_ / "session");
    ASSERT_TRUE(s) << s.error().describe();
    session_.emplace(std::move(s.value()));
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Rewrites view `view`'s HDR image after `change` altered it.
  void alter_view(int view, const std::function<void(calib::HdrImage&)>& change) {
    const fs::path file = session_->layout().hdr_file(view);
    auto hdr = calib::read_hdr_exr(file);
    ASSERT_TRUE(hdr) << hdr.error().describe();
    change(hdr.value());
    ASSERT_TRUE(calib::write_hdr_exr(file, hdr.value(), ExrPixelType::kFloat));
  }

  fs::path dir_;
  std::optional<capture::Session> session_;
};

TEST_F(ViewChecks, NonFinitePixelsAreMaskedNotSampled) {
  const int view = session_->manifest().views.at(0).index;  // the normal view: sees every texel
  alter_view(view, [](calib::HdrImage& h) {
    // A block of NaN and Inf in the middle of the surface, and one NaN pixel.
    h.radiance(cv::Rect(h.width() / 2 - 8, h.height() / 2 - 8, 16, 16)).setTo(cv::Scalar::all(NAN));
    h.radiance.at<cv::Vec3f>(h.height() / 2 + 10, h.width() / 2 + 10)[1] = std::numeric_limits<float>::infinity();
  });
  auto map = build_session_obsmap(session_.value(), 16, 16);
  ASSERT_TRUE(map) << map.error().describe();
  int valid = 0;
  for (int t = 0; t < 16; ++t)
    for (int s = 0; s < 16; ++s) {
      const auto obs = map->texel(s, t);
      for (size_t i = 0; i < obs.size(); ++i) {
        ASSERT_TRUE(obs.radiance[i].allFinite()) << "texel " << s << "," << t << " view " << obs.view[i];
        ++valid;
      }
    }
  EXPECT_GT(valid, 0);

  // The streamed file gives the same: every stored valid observation finite.
  const fs::path file = dir_ / "map.vdobs";
  ASSERT_TRUE(build_session_obsmap_file(session_.value(), 16, 16, file));
  auto reader = fitting::ObsMapReader::open(file);
  ASSERT_TRUE(reader) << reader.error().describe();
  auto streamed = reader->read_all();
  ASSERT_TRUE(streamed) << streamed.error().describe();
  for (int t = 0; t < 16; ++t)
    for (int s = 0; s < 16; ++s) {
      const auto obs = streamed->texel(s, t);
      for (size_t i = 0; i < obs.size(); ++i)
        ASSERT_TRUE(obs.radiance[i].allFinite()) << "file: texel " << s << "," << t << " view " << obs.view[i];
    }
}

TEST_F(ViewChecks, WrongSizeViewIsRefused) {
  const int view = session_->manifest().views.at(1).index;
  alter_view(view, [](calib::HdrImage& h) {
    cv::resize(h.radiance, h.radiance, cv::Size(h.width() / 2, h.height() / 2), 0, 0, cv::INTER_NEAREST);
    cv::resize(h.mask, h.mask, h.radiance.size(), 0, 0, cv::INTER_NEAREST);
  });
  for (int pass = 0; pass < 2; ++pass) {
    Status s = pass == 0 ? build_session_obsmap(session_.value(), 16, 16).status()
                         : build_session_obsmap_file(session_.value(), 16, 16, dir_ / "map.vdobs");
    ASSERT_FALSE(s) << "pass " << pass;
    EXPECT_EQ(s.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(s.error().message.find("48x36, the camera 96x72"), std::string::npos) << s.error().message;
  }
}

}  // namespace
}  // namespace vdrig::pipeline

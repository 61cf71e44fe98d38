// vdrig's HDR merge against OpenCV's cv::MergeDebevec on the same synthetic bracket, both given the true response
// (issue #26: the merge's accuracy held against a peer; bench_hdr_merge has the 1024x768 speed figures, docs/calib.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/photo.hpp>
#include <vector>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/calib/synthetic.hpp"

namespace vdrig::calib {
namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

/// Median |merged / truth - 1| over the pixel-channels some exposure saw unclipped; `merged` CV_32FC3 in the frames'
/// channel order.
double median_error(const SyntheticBracket& b, const cv::Mat& merged) {
  std::vector<double> all;
  for (int y = 0; y < merged.rows; ++y)
    for (int x = 0; x < merged.cols; ++x)
      for (int c = 0; c < 3; ++c) {
        const double truth = b.radiance.ptr<float>(y)[3 * x + c];
        bool unclipped = false;
        for (const auto& f : b.frames) {
          const int z = f.image.ptr<uint8_t>(y)[3 * x + c];
          unclipped = unclipped || (z > 0 && z < 255);
        }
        if (truth > 0 && unclipped) all.push_back(std::abs(merged.ptr<float>(y)[3 * x + c] / truth - 1.0));
      }
  return percentile(all, 0.5);
}

TEST(HdrAgainstOpenCv, MergeIsMoreAccurateThanMergeDebevec) {
  const auto response = ResponseCurve::s_curve(8);
  // OpenCV's CRF: code -> exposure, B, G, R like the images (ResponseCurve is R, G, B). It takes log(CRF), so code 0
  // gets the exposure of half a code instead of -inf.
  cv::Mat crf(256, 1, CV_32FC3);
  for (int z = 0; z < 256; ++z)
    for (int c = 0; c < 3; ++c)
      crf.at<cv::Vec3f>(z)[c] = static_cast<float>(z == 0 ? response.inverse(2 - c, 0.5) : response.inverse(2 - c, z));
  auto debevec = cv::createMergeDebevec();
  // Measured (256x192, the default bracket): vdrig 0.391 % / 1.524 %, MergeDebevec 1.199 % / 2.776 %, noise-free /
  // sigma 1 code; docs/calib.md has the same at 1024x768. Bounds 1.5x; OpenCV's own bound checks the peer is fed right.
  const double ours_bound[] = {0.0059, 0.023}, theirs_bound[] = {0.018, 0.042};
  int k = 0;
  for (const double noise : {0.0, 1.0}) {
    SyntheticBracketOptions opt;
    opt.noise_codes = noise;
    const auto b = make_synthetic_bracket(response, opt);
    std::vector<cv::Mat> images;
    std::vector<float> times;
    for (const auto& f : b.frames) {
      images.push_back(f.image);
      times.push_back(static_cast<float>(f.exposure_s));
    }
    auto ours = merge_hdr(b.frames, response);
    ASSERT_TRUE(ours) << ours.error().describe();
    cv::Mat theirs;
    debevec->process(images, theirs, times, crf);
    const double e_ours = median_error(b, ours->radiance), e_cv = median_error(b, theirs);
    std::printf("noise %.0f code(s): median relative error vdrig %.3f %%, cv::MergeDebevec %.3f %%\n", noise,
                100 * e_ours, 100 * e_cv);
    EXPECT_LT(e_ours, ours_bound[k]);
    EXPECT_LT(e_cv, theirs_bound[k]);
    EXPECT_LT(1.5 * e_ours, e_cv) << "vdrig's merge is 1.8x (noisy) to 3x (clean) closer to the truth";
    ++k;
  }
}

}  // namespace
}  // namespace vdrig::calib

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

TEST(HdrAgainstOpenCv, MergeIsMoreAccurateThanMergeDebevec) {
  const auto response = ResponseCurve::s_curve(8);
  const cv::Mat crf = opencv_crf(response);  // the true response, as OpenCV takes it
  auto debevec = cv::createMergeDebevec();
  // Measured (256x192, the default bracket): vdrig 0.391 % / 1.524 %, MergeDebevec 1.199 % / 2.776 %, noise-free /
  // sigma 1 code; docs/calib.md has the same at 1024x768. Bounds 1.5x; OpenCV's own bound checks the peer is fed right.
  const double ours_bound[] = {0.0059, 0.023}, theirs_bound[] = {0.018, 0.042};
  int k = 0;
  for (const double noise : {0.0, 1.0}) {
    SyntheticBracketOptions opt;
    opt.noise_codes = noise;
    const auto b = make_synthetic_bracket(response, opt);
    const OpenCvBracket cv_bracket = opencv_bracket(b);
    auto ours = merge_hdr(b.frames, response);
    ASSERT_TRUE(ours) << ours.error().describe();
    cv::Mat theirs;
    debevec->process(cv_bracket.images, theirs, cv_bracket.times_s, crf);
    const double e_ours = merge_errors(b, ours->radiance).median, e_cv = merge_errors(b, theirs).median;
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

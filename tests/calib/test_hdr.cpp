// HDR path against ground truth: synthetic brackets from a known radiance field through a known response curve.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/calib/response_recovery.hpp"
#include "vdrig/calib/synthetic.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::calib {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

bool any_unclipped(const std::vector<Frame>& frames, int y, int x, int c, int max_code) {
  for (const auto& f : frames) {
    const int z = f.image.depth() == CV_8U ? f.image.ptr<uint8_t>(y)[3 * x + c] : f.image.ptr<uint16_t>(y)[3 * x + c];
    if (z > 0 && z < max_code) return true;
  }
  return false;
}

/// |merged * scale / truth - 1| over every pixel-channel that some exposure saw unclipped; scale = 1 or, if
/// `fit_scale`, the median ratio truth / merged (a recovered response is known only up to scale).
std::vector<double> relative_errors(const SyntheticBracket& b, const HdrImage& hdr, int max_code, bool fit_scale,
                                    double* scale_out = nullptr) {
  std::vector<double> ratio;
  for (int y = 0; y < hdr.height(); ++y)
    for (int x = 0; x < hdr.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double truth = b.radiance.ptr<float>(y)[3 * x + c];
        if (truth <= 0 || !any_unclipped(b.frames, y, x, c, max_code)) continue;
        ratio.push_back(truth / hdr.radiance.ptr<float>(y)[3 * x + c]);
      }
  const double scale = fit_scale ? median(ratio) : 1.0;
  if (scale_out) *scale_out = scale;
  std::vector<double> err;
  err.reserve(ratio.size());
  for (double r : ratio) err.push_back(std::abs(scale / r - 1.0));
  return err;
}

TEST(HdrWeight, ExactlyZeroAtClippedCodes) {
  EXPECT_EQ(hdr_hat_weight(0, 255), 0.0f);
  EXPECT_EQ(hdr_hat_weight(255, 255), 0.0f);
  EXPECT_EQ(hdr_hat_weight(300, 255), 0.0f);
  EXPECT_GT(hdr_hat_weight(1, 255), 0.0f);
  EXPECT_GT(hdr_hat_weight(254, 255), 0.0f);
  EXPECT_NEAR(hdr_hat_weight(127, 255), 127.0 / 127.5, 1e-6);
  EXPECT_EQ(hdr_hat_weight(4095, 4095), 0.0f);
}

TEST(HdrMerge, TrueResponseNoiseFreeMatchesGroundTruth) {
  const auto resp = ResponseCurve::s_curve(8);
  const auto b = make_synthetic_bracket(resp);
  auto hdr = merge_hdr(b.frames, resp);
  ASSERT_TRUE(hdr) << hdr.error().describe();
  const auto err = relative_errors(b, *hdr, 255, false);
  ASSERT_GT(err.size(), 100000u);
  const double med = median(err);
  RecordProperty("median_rel_error", std::to_string(med));
  std::printf("noise-free, true response: median relative error %.4f%% over %zu samples\n", 100 * med, err.size());
  EXPECT_LT(med, 0.02);
  EXPECT_LT(med, 0.005) << "noise-free 8-bit merge should be well under 1%";
}

TEST(HdrMerge, TrueResponseNoisyMatchesGroundTruth) {
  const auto resp = ResponseCurve::s_curve(8);
  SyntheticBracketOptions o;
  o.noise_codes = 1.0;
  const auto b = make_synthetic_bracket(resp, o);
  auto hdr = merge_hdr(b.frames, resp);
  ASSERT_TRUE(hdr) << hdr.error().describe();
  const double med = median(relative_errors(b, *hdr, 255, false));
  std::printf("noisy (1 code), true response: median relative error %.4f%%\n", 100 * med);
  EXPECT_LT(med, 0.02);
}

TEST(HdrMerge, MaskAndFallbackWhereEveryExposureIsClipped) {
  const auto resp = ResponseCurve::s_curve(8);
  const auto b = make_synthetic_bracket(resp);
  auto hdr = merge_hdr(b.frames, resp);
  ASSERT_TRUE(hdr);
  const double t_short = b.frames.front().exposure_s, t_long = b.frames.back().exposure_s;
  int saturated = 0, black = 0;
  for (int y = 0; y < hdr->height(); ++y)
    for (int x = 0; x < hdr->width(); ++x) {
      bool all_sat = false, all_black = false;
      for (int c = 0; c < 3; ++c) {
        bool s = true, k = true;
        for (const auto& f : b.frames) {
          const int z = f.image.ptr<uint8_t>(y)[3 * x + c];
          s = s && z == 255;
          k = k && z == 0;
        }
        const float v = hdr->radiance.ptr<float>(y)[3 * x + c];
        if (s) {
          EXPECT_FLOAT_EQ(v, static_cast<float>(resp.inverse(2 - c, 255) / t_short));
        }
        if (k) {
          EXPECT_FLOAT_EQ(v, static_cast<float>(resp.inverse(2 - c, 0) / t_long));
        }
        all_sat = all_sat || s;
        all_black = all_black || k;
      }
      const uint8_t m = hdr->mask.at<uint8_t>(y, x);
      ASSERT_EQ((m & kHdrSaturated) != 0, all_sat) << "at " << x << "," << y;
      ASSERT_EQ((m & kHdrBlack) != 0, all_black) << "at " << x << "," << y;
      saturated += all_sat;
      black += all_black;
    }
  // The synthetic field has black rows and a saturated bright end: both cases must really occur.
  EXPECT_GT(saturated, 100);
  EXPECT_GE(black, 4 * hdr->width());
  EXPECT_EQ(hdr->mask.at<uint8_t>(0, 0), kHdrBlack);
}

TEST(HdrMerge, SaturatedLongExposureGetsZeroWeight) {
  const auto resp = ResponseCurve::s_curve(8);
  const auto b = make_synthetic_bracket(resp);
  auto full = merge_hdr(b.frames, resp);
  ASSERT_TRUE(full);
  // Dropping the longest exposure must not change any pixel that exposure saw saturated (or black).
  std::vector<Frame> shorter(b.frames.begin(), b.frames.end() - 1);
  auto partial = merge_hdr(shorter, resp);
  ASSERT_TRUE(partial);
  int checked = 0;
  for (int y = 0; y < full->height(); ++y)
    for (int x = 0; x < full->width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const int z_long = b.frames.back().image.ptr<uint8_t>(y)[3 * x + c];
        if (z_long != 255 || !any_unclipped(shorter, y, x, c, 255)) continue;
        ASSERT_EQ(full->radiance.ptr<float>(y)[3 * x + c], partial->radiance.ptr<float>(y)[3 * x + c])
            << "pixel saturated in the long exposure took a value from it at " << x << "," << y;
        ++checked;
      }
  EXPECT_GT(checked, 10000);
  // And a saturated code really is excluded: force it to mid-grey in the long frame and the result moves.
  std::vector<Frame> tampered = b.frames;
  tampered.back().image = b.frames.back().image.clone();
  const int x = full->width() - 20, y = full->height() / 2;
  ASSERT_EQ(tampered.back().image.ptr<uint8_t>(y)[3 * x + 1], 255);
  tampered.back().image.ptr<uint8_t>(y)[3 * x + 1] = 128;
  auto moved = merge_hdr(tampered, resp);
  ASSERT_TRUE(moved);
  EXPECT_NE(moved->radiance.ptr<float>(y)[3 * x + 1], full->radiance.ptr<float>(y)[3 * x + 1]);
}

void check_recovery(double noise_codes, double curve_tol, double merge_tol) {
  const auto truth = ResponseCurve::s_curve(8);
  SyntheticBracketOptions o;
  o.noise_codes = noise_codes;
  const auto b = make_synthetic_bracket(truth, o);
  auto rec = recover_response(b.frames);
  ASSERT_TRUE(rec) << rec.error().describe();
  for (int c = 0; c < 3; ++c) EXPECT_GE(rec->samples[c], 200);
  // Documented scale: channels equal at mid code; saturation near X = 1 (checked on the merge's scale below).
  EXPECT_NEAR(rec->curve.inverse(0, 127) / rec->curve.inverse(2, 127), 1.0, 0.005);
  EXPECT_NEAR(rec->curve.inverse(1, 127) / rec->curve.inverse(2, 127), 1.0, 0.005);
  // Compare shapes after fixing the scale at the mid code, over codes seen well by the bracket.
  double worst = 0;
  for (int c = 0; c < 3; ++c) {
    const double k = truth.inverse(c, 128) / rec->curve.inverse(c, 128);
    for (int z = 16; z <= 240; ++z)
      worst = std::max(worst, std::abs(k * rec->curve.inverse(c, z) / truth.inverse(c, z) - 1.0));
  }
  std::printf("noise %.1f codes: recovered response worst relative deviation over codes 16..240: %.3f%%\n", noise_codes,
              100 * worst);
  EXPECT_LT(worst, curve_tol);
  if (std::getenv("VDRIG_DUMP_CURVE"))
    for (int z = 0; z < 256; z += 4)
      std::printf("z %3d true %.5g rec %.5g ratio %.4f\n", z, truth.inverse(1, z), rec->curve.inverse(1, z),
                  rec->curve.inverse(1, z) / truth.inverse(1, z));
  auto hdr = merge_hdr(b.frames, rec->curve);
  ASSERT_TRUE(hdr);
  double scale = 0;
  const double med = median(relative_errors(b, *hdr, 255, true, &scale));
  std::printf("noise %.1f codes: merge with recovered response: median relative error %.4f%% (scale %.4g)\n",
              noise_codes, 100 * med, scale);
  EXPECT_LT(med, merge_tol);
  // Same units as the true curve (X = 1 saturates) to within 20 %: the merge needs no rescaling to be usable.
  EXPECT_GT(scale, 0.8);
  EXPECT_LT(scale, 1.25);
}

TEST(ResponseRecovery, NoiseFreeMatchesTrueCurve) { check_recovery(0.0, 0.03, 0.02); }
TEST(ResponseRecovery, NoisyMatchesTrueCurve) { check_recovery(1.0, 0.05, 0.02); }

TEST(ResponseRecovery, DescendingBracketGivesTheSameCurve) {
  const auto truth = ResponseCurve::s_curve(8);
  auto b = make_synthetic_bracket(truth);
  auto up = recover_response(b.frames);
  std::reverse(b.frames.begin(), b.frames.end());
  auto down = recover_response(b.frames);
  ASSERT_TRUE(up && down);
  for (int z = 1; z < 255; ++z) EXPECT_NEAR(up->curve.inverse(0, z), down->curve.inverse(0, z), 1e-6);
}

// ResponseCurve channels are R, G, B while images are B, G, R (the simulator's convention): check with three
// different curves that each image channel goes through the right one, in rendering, merging and recovery.
TEST(HdrChannels, ResponseIsIndexedRgbImagesBgr) {
  const auto lin = ResponseCurve::linear(8), s22 = ResponseCurve::s_curve(8, 2.2, 1.3),
             s14 = ResponseCurve::s_curve(8, 1.4, 1.0);
  auto mixed = ResponseCurve::from_inverse(8, {lin.inverse_table(0), s22.inverse_table(0), s14.inverse_table(0)});
  ASSERT_TRUE(mixed);
  const auto b = make_synthetic_bracket(*mixed);
  // Image channel 2 is red: linear codes.
  const int x = b.radiance.cols / 2, y = b.radiance.rows / 2;
  const auto& f = b.frames[2];
  const double t = f.exposure_s;
  EXPECT_EQ(f.image.ptr<uint8_t>(y)[3 * x + 2], std::lround(lin.forward(0, b.radiance.ptr<float>(y)[3 * x + 2] * t)));
  EXPECT_EQ(f.image.ptr<uint8_t>(y)[3 * x + 0], std::lround(s14.forward(0, b.radiance.ptr<float>(y)[3 * x + 0] * t)));
  auto hdr = merge_hdr(b.frames, *mixed);
  ASSERT_TRUE(hdr);
  EXPECT_LT(median(relative_errors(b, *hdr, 255, false)), 0.02);
  // Recovery puts each image channel's curve in the right slot: R comes out linear (log slope 1 against code).
  auto rec = recover_response(b.frames);
  ASSERT_TRUE(rec) << rec.error().describe();
  for (int rc = 0; rc < 3; ++rc) {
    const auto& truth = rc == 0 ? lin : rc == 1 ? s22 : s14;
    const double k = truth.inverse(0, 128) / rec->curve.inverse(rc, 128);
    for (int z : {32, 64, 192, 224})
      EXPECT_NEAR(k * rec->curve.inverse(rc, z) / truth.inverse(0, z), 1.0, 0.05) << "channel " << rc << " code " << z;
  }
}

TEST(HdrMerge, LinearRawCameraWithoutCurve) {
  const auto lin = ResponseCurve::linear(12);
  SyntheticBracketOptions o;
  o.exposures_s = {1.0 / 1024, 1.0 / 128, 1.0 / 16};
  o.noise_codes = 2.0;
  const auto b = make_synthetic_bracket(lin, o);
  ASSERT_EQ(b.frames[0].image.type(), CV_16UC3);
  auto hdr = merge_hdr(b.frames, ResponseCurve{});  // empty: linear in the frames' 12 bits
  ASSERT_TRUE(hdr) << hdr.error().describe();
  const double med = median(relative_errors(b, *hdr, 4095, false));
  std::printf("linear 12-bit, noise 2 codes: median relative error %.4f%%\n", 100 * med);
  EXPECT_LT(med, 0.02);
}

TEST(HdrIo, ExrRoundTripHalfAndFloat) {
  const auto resp = ResponseCurve::s_curve(8);
  const auto b = make_synthetic_bracket(resp, {.width = 64, .height = 48});
  auto hdr = merge_hdr(b.frames, resp);
  ASSERT_TRUE(hdr);
  const test::TempDir dir("hdr_io");
  for (auto type : {ExrPixelType::kHalf, ExrPixelType::kFloat}) {
    const auto path = dir / (type == ExrPixelType::kHalf ? "half.exr" : "float.exr");
    const auto st = write_hdr_exr(path, *hdr, type);
    ASSERT_TRUE(st) << st.describe();
    auto back = read_hdr_exr(path);
    ASSERT_TRUE(back) << back.error().describe();
    EXPECT_EQ(cv::norm(back->mask, hdr->mask, cv::NORM_INF), 0.0);
    cv::Mat rel;
    cv::absdiff(back->radiance, hdr->radiance, rel);
    cv::divide(rel, hdr->radiance + 1e-30, rel);
    double worst;
    cv::minMaxLoc(rel.reshape(1), nullptr, &worst);
    EXPECT_LT(worst, type == ExrPixelType::kHalf ? 1e-3 : 1e-7);
    ASSERT_EQ(back->exposures_s.size(), hdr->exposures_s.size());
    for (size_t i = 0; i < hdr->exposures_s.size(); ++i)
      EXPECT_NEAR(back->exposures_s[i], hdr->exposures_s[i], 1e-9 * hdr->exposures_s[i]);
    EXPECT_EQ(back->bits, 8);
  }
  EXPECT_FALSE(read_hdr_exr(dir / "missing.exr"));
}

TEST(HdrInput, BadBracketsAreErrorValues) {
  const auto resp = ResponseCurve::s_curve(8);
  const auto good = make_synthetic_bracket(resp, {.width = 32, .height = 24, .exposures_s = {0.01, 0.02, 0.04}});
  auto expect_bad = [&](std::vector<Frame> frames, const ResponseCurve& r, const std::string& needle) {
    auto res = merge_hdr(frames, r);
    ASSERT_FALSE(res) << "accepted a bracket that should fail with '" << needle << "'";
    EXPECT_EQ(res.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(res.error().message.find(needle), std::string::npos) << res.error().message;
  };
  ASSERT_TRUE(merge_hdr(good.frames, resp));
  expect_bad({}, resp, "empty bracket");
  {
    auto f = good.frames;
    cv::resize(f[1].image, f[1].image, {16, 12});
    expect_bad(f, resp, "frame 1 is 16x12");
  }
  {
    auto f = good.frames;
    f[2].image.convertTo(f[2].image, CV_16U);
    f[2].bits = 8;
    expect_bad(f, resp, "frame 2 is CV_16UC3");
  }
  {
    auto f = good.frames;
    cv::cvtColor(f[0].image, f[0].image, cv::COLOR_BGR2GRAY);
    expect_bad(f, resp, "want CV_8UC3 or CV_16UC3");
  }
  {
    auto f = good.frames;
    f[2].exposure_s = 0.01;
    expect_bad(f, resp, "duplicate exposure");
  }
  {
    auto f = good.frames;
    std::swap(f[1], f[2]);
    expect_bad(f, resp, "not monotonic");
  }
  {
    auto f = good.frames;
    f[1].exposure_s = 0;
    expect_bad(f, resp, "no valid exposure time");
  }
  {
    auto f = good.frames;
    f[1].exposure_s = NAN;
    expect_bad(f, resp, "no valid exposure time");
  }
  expect_bad(good.frames, ResponseCurve::s_curve(10), "response curve has 10 bits");
  {
    auto f = good.frames;
    for (auto& fr : f) fr.bits = 10;
    expect_bad(f, resp, "claims 10 bits in a 8-bit image");
  }
  auto one = recover_response(std::vector<Frame>{good.frames[0]});
  ASSERT_FALSE(one);
  EXPECT_NE(one.error().message.find("at least 2"), std::string::npos) << one.error().message;
  // A single frame is a valid (if low-range) merge.
  EXPECT_TRUE(merge_hdr(std::vector<Frame>{good.frames[1]}, resp));
}

}  // namespace
}  // namespace vdrig::calib

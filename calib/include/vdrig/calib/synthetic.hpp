// Synthetic exposure brackets with known radiance, for tests, benchmarks and demos of the HDR path.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "vdrig/core/frame.hpp"
#include "vdrig/core/response.hpp"

namespace vdrig::calib {

struct SyntheticBracketOptions {
  int width = 256;
  int height = 192;
  /// Exposure times, seconds (any order; frames come out in this order). Default: 5 exposures 4x apart.
  std::vector<double> exposures_s = {1.0 / 1024, 1.0 / 256, 1.0 / 64, 1.0 / 16, 1.0 / 4};
  /// Radiance spans 10^-decades .. 1 times `peak_radiance` along a smooth diagonal gradient.
  double decades = 5.0;
  /// Peak radiance (X per second): with the default exposures, 1400 saturates even the shortest exposure (X > 1) in
  /// the brightest ~3% of columns, so those are saturated everywhere.
  double peak_radiance = 1400.0;
  /// Rows at the top with zero radiance (black in every exposure), to exercise the all-black case.
  int black_rows = 4;
  /// Gaussian noise added to the continuous code before quantisation, in codes (0: noise-free).
  double noise_codes = 0.0;
  unsigned seed = 7;
};

struct SyntheticBracket {
  std::vector<Frame> frames;  // CV_8UC3 (bits <= 8) or CV_16UC3, BGR, exposure_s set, gain 1
  cv::Mat radiance;           // ground-truth relative radiance, CV_32FC3 (B, G, R), in the response's X per second
};

/// Renders the radiance field E(x, y, c) through code = round(f_c(E t) + noise), clipped to [0, max_code].
/// Channels get slightly different radiance (a colour tint) and a gentle vertical ripple so rows differ.
SyntheticBracket make_synthetic_bracket(const ResponseCurve& response, const SyntheticBracketOptions& options = {});

/// A merge's error against an 8-bit bracket's truth: |merged / truth - 1| over the pixel-channels that some exposure
/// saw unclipped (0 < code < 255); its median and 95th percentile, and the median over those the last (longest)
/// exposure saturated. NaN where there is no such pixel-channel. `merged`: CV_32FC3 in the frames' channel order.
struct MergeErrors {
  double median = 0, p95 = 0, median_long_clipped = 0;
};
MergeErrors merge_errors(const SyntheticBracket& bracket, const cv::Mat& merged);

/// An 8-bit response as OpenCV's HDR merges take their camera response (CRF): 256x1 CV_32FC3, code -> exposure, in
/// the images' B, G, R order (ResponseCurve's channels are R, G, B). OpenCV takes log(CRF), so code 0 (exposure 0 on
/// the true curve) gets the exposure of half a code instead of -inf.
cv::Mat opencv_crf(const ResponseCurve& response);

/// The bracket's frames as OpenCV's HDR merges take them: the images and their exposure times (seconds, as float).
struct OpenCvBracket {
  std::vector<cv::Mat> images;
  std::vector<float> times_s;
};
OpenCvBracket opencv_bracket(const SyntheticBracket& bracket);

}  // namespace vdrig::calib

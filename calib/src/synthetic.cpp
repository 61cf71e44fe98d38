#include "vdrig/calib/synthetic.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/core/utility.hpp>
#include <random>

namespace vdrig::calib {

SyntheticBracket make_synthetic_bracket(const ResponseCurve& response, const SyntheticBracketOptions& o) {
  VDRIG_CHECK(!response.empty(), "synthetic bracket needs a response curve");
  VDRIG_CHECK(o.width > 0 && o.height > 0 && !o.exposures_s.empty(), "synthetic bracket needs a size and exposures");
  const int W = o.width, H = o.height, max_code = response.max_code();
  SyntheticBracket out;
  out.radiance.create(H, W, CV_32FC3);
  const double tint[3] = {0.7, 1.0, 0.85};  // B, G, R
  for (int y = 0; y < H; ++y) {
    float* e = out.radiance.ptr<float>(y);
    const double v = H > 1 ? double(y) / (H - 1) : 0.0;
    for (int x = 0; x < W; ++x) {
      const double u = W > 1 ? double(x) / (W - 1) : 0.0;
      // Smooth diagonal gradient in log radiance: 0.9 of the span along x, 0.1 along y, plus a small ripple.
      const double s = 0.9 * u + 0.1 * v;
      const double base = o.peak_radiance * std::pow(10.0, -o.decades * (1.0 - s)) *
                          (1.0 + 0.05 * std::sin(2 * std::numbers::pi * 3 * v));
      for (int c = 0; c < 3; ++c) e[3 * x + c] = y < o.black_rows ? 0.0f : static_cast<float>(base * tint[c]);
    }
  }
  const int type = response.bits() <= 8 ? CV_8UC3 : CV_16UC3;
  for (size_t j = 0; j < o.exposures_s.size(); ++j) {
    Frame f;
    f.exposure_s = o.exposures_s[j];
    f.bits = response.bits();
    f.sequence = j;
    f.image.create(H, W, type);
    const double t = o.exposures_s[j];
    cv::parallel_for_(cv::Range(0, H), [&](const cv::Range& rows) {
      for (int y = rows.start; y < rows.end; ++y) {
        // Noise seeded per (frame, row): deterministic whatever the thread split.
        std::mt19937 rng(o.seed * 7919u + static_cast<unsigned>(j) * 104729u + static_cast<unsigned>(y));
        std::normal_distribution<double> noise(0.0, o.noise_codes > 0 ? o.noise_codes : 1.0);
        const float* e = out.radiance.ptr<float>(y);
        for (int x = 0; x < W; ++x)
          for (int c = 0; c < 3; ++c) {
            double code = response.forward(2 - c, e[3 * x + c] * t);  // BGR image, response indexed R, G, B
            if (o.noise_codes > 0) code += noise(rng);
            const int q = static_cast<int>(std::lround(std::clamp(code, 0.0, double(max_code))));
            if (type == CV_8UC3)
              f.image.ptr<uint8_t>(y)[3 * x + c] = static_cast<uint8_t>(q);
            else
              f.image.ptr<uint16_t>(y)[3 * x + c] = static_cast<uint16_t>(q);
          }
      }
    });
    out.frames.push_back(std::move(f));
  }
  return out;
}

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace

MergeErrors merge_errors(const SyntheticBracket& b, const cv::Mat& merged) {
  std::vector<double> all, long_clipped;
  for (int y = 0; y < merged.rows; ++y)
    for (int x = 0; x < merged.cols; ++x)
      for (int c = 0; c < 3; ++c) {
        const double truth = b.radiance.ptr<float>(y)[3 * x + c];
        bool unclipped = false;
        for (const auto& f : b.frames) {
          const int z = f.image.ptr<uint8_t>(y)[3 * x + c];
          unclipped = unclipped || (z > 0 && z < 255);
        }
        if (truth <= 0 || !unclipped) continue;
        const double e = std::abs(merged.ptr<float>(y)[3 * x + c] / truth - 1.0);
        all.push_back(e);
        if (b.frames.back().image.ptr<uint8_t>(y)[3 * x + c] == 255) long_clipped.push_back(e);
      }
  return {percentile(all, 0.5), percentile(all, 0.95), percentile(long_clipped, 0.5)};
}

cv::Mat opencv_crf(const ResponseCurve& response) {
  cv::Mat crf(256, 1, CV_32FC3);
  for (int z = 0; z < 256; ++z)
    for (int c = 0; c < 3; ++c)
      crf.at<cv::Vec3f>(z)[c] = static_cast<float>(z == 0 ? response.inverse(2 - c, 0.5) : response.inverse(2 - c, z));
  return crf;
}

OpenCvBracket opencv_bracket(const SyntheticBracket& bracket) {
  OpenCvBracket out;
  for (const auto& f : bracket.frames) {
    out.images.push_back(f.image);
    out.times_s.push_back(static_cast<float>(f.exposure_s));
  }
  return out;
}

}  // namespace vdrig::calib

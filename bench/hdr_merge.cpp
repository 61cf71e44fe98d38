// HDR merge, vdrig vs OpenCV's MergeDebevec, side by side in one process on the same synthetic bracket:
// 5 exposures (2 stops apart) of a 1024x768 radiance gradient spanning 5 decades, through the core S-curve,
// quantised to 8 bits and clipped. OpenCV gets the same true response as its CRF.
// Prints megapixels per second (output pixels) and the median / 95th-percentile relative error against ground truth
// over the pixel-channels that at least one exposure saw unclipped.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <opencv2/core/utility.hpp>
#include <opencv2/photo.hpp>
#include <vector>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/calib/synthetic.hpp"

using namespace vdrig;
using namespace vdrig::calib;

namespace {

struct Errors {
  double median = 0, p95 = 0, median_long_clipped = 0;
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

// `merged`: CV_32FC3 in the same channel order as the frames.
Errors errors(const SyntheticBracket& b, const cv::Mat& merged) {
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

template <typename F>
double median_seconds(int reps, F&& f) {
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return percentile(t, 0.5);
}

}  // namespace

int main() {
  const auto response = ResponseCurve::s_curve(8);
  SyntheticBracketOptions opt;
  opt.width = 1024;
  opt.height = 768;

  // OpenCV's CRF: code -> exposure X, 256x1 CV_32FC3. It takes log(CRF), so code 0 (X = 0 in the true curve) gets
  // the exposure of half a code instead of -inf.
  cv::Mat crf(256, 1, CV_32FC3);
  for (int z = 0; z < 256; ++z)
    for (int c = 0; c < 3; ++c)
      crf.at<cv::Vec3f>(z)[c] =  // OpenCV's CRF follows the image's B, G, R; ResponseCurve is R, G, B
          static_cast<float>(z == 0 ? response.inverse(2 - c, 0.5) : response.inverse(2 - c, z));
  auto merge_debevec = cv::createMergeDebevec();

  const int threads = cv::getNumThreads();
  const double mpix = opt.width * opt.height / 1e6;
  std::printf("HDR merge of %zu exposures of %dx%d (8-bit, S-curve response), %d OpenCV thread(s) available\n\n",
              opt.exposures_s.size(), opt.width, opt.height, threads);
  std::printf("%-8s %-22s %9s %10s %10s %12s %18s\n", "stack", "method", "threads", "ms", "MP/s", "median err",
              "p95 err / long-sat");
  for (double noise : {0.0, 1.0}) {
    opt.noise_codes = noise;
    const auto b = make_synthetic_bracket(response, opt);
    std::vector<cv::Mat> images;
    std::vector<float> times;
    for (const auto& f : b.frames) {
      images.push_back(f.image);
      times.push_back(static_cast<float>(f.exposure_s));
    }
    const char* stack = noise > 0 ? "noisy" : "clean";
    for (int nthreads : {threads, 1}) {
      if (nthreads == 1 && threads == 1) continue;
      cv::setNumThreads(nthreads);
      const auto row = [&](const char* method, double seconds, const Errors& e) {
        std::printf("%-8s %-22s %9d %10.2f %10.1f %11.3f%% %8.2f%% / %.2f%%\n", stack, method, nthreads, 1e3 * seconds,
                    mpix / seconds, 100 * e.median, 100 * e.p95, 100 * e.median_long_clipped);
      };
      HdrImage ours;
      const double t_ours = median_seconds(7, [&] { ours = *merge_hdr(b.frames, response); });
      cv::Mat theirs;
      const double t_cv = median_seconds(5, [&] { merge_debevec->process(images, theirs, times, crf); });
      row("vdrig merge_hdr", t_ours, errors(b, ours.radiance));
      row("cv::MergeDebevec", t_cv, errors(b, theirs));
    }
    cv::setNumThreads(threads);
  }
  std::printf(
      "\nerrors: |merged / truth - 1| over pixel-channels some exposure saw unclipped; 'long-sat' = median over\n"
      "those saturated in the longest exposure (where counting clipped codes hurts).\n");
  return 0;
}

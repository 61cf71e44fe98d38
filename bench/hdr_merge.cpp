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

template <typename F>
double median_seconds(int reps, F&& f) {
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(t.begin(), t.begin() + reps / 2, t.end());
  return t[reps / 2];
}

}  // namespace

int main() {
  const auto response = ResponseCurve::s_curve(8);
  SyntheticBracketOptions opt;
  opt.width = 1024;
  opt.height = 768;

  const cv::Mat crf = opencv_crf(response);  // the true response, as OpenCV takes it
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
    const OpenCvBracket cv_bracket = opencv_bracket(b);
    const char* stack = noise > 0 ? "noisy" : "clean";
    for (int nthreads : {threads, 1}) {
      if (nthreads == 1 && threads == 1) continue;
      cv::setNumThreads(nthreads);
      const auto row = [&](const char* method, double seconds, const MergeErrors& e) {
        std::printf("%-8s %-22s %9d %10.2f %10.1f %11.3f%% %8.2f%% / %.2f%%\n", stack, method, nthreads, 1e3 * seconds,
                    mpix / seconds, 100 * e.median, 100 * e.p95, 100 * e.median_long_clipped);
      };
      HdrImage ours;
      const double t_ours = median_seconds(7, [&] { ours = *merge_hdr(b.frames, response); });
      cv::Mat theirs;
      const double t_cv =
          median_seconds(5, [&] { merge_debevec->process(cv_bracket.images, theirs, cv_bracket.times_s, crf); });
      row("vdrig merge_hdr", t_ours, merge_errors(b, ours.radiance));
      row("cv::MergeDebevec", t_cv, merge_errors(b, theirs));
    }
    cv::setNumThreads(threads);
  }
  std::printf(
      "\nerrors: |merged / truth - 1| over pixel-channels some exposure saw unclipped; 'long-sat' = median over\n"
      "those saturated in the longest exposure (where counting clipped codes hurts).\n");
  return 0;
}

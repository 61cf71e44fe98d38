// Lighting a virtual object that moves through a room (docs/probe.md, "The moving object"): four probes rendered
// analytically in a synthetic box room (walls with gradients, a window, a ceiling lamp) are fused at the object's
// position on each of 300 frames of a closed path, and the fused map is turned into lights: median cut per frame
// (the baseline), SH-9, hybrid and soft lights (soft_lights.hpp, the stable method). For every method:
//  - per-frame error: mean over 64 normals of |E - E_exact| / mean E_exact, E_exact the exact convolution of the
//    frame's fused map;
//  - excess flicker: mean over normals of |dE - dE_exact| / mean E_exact, d the change from the previous frame
//    (what the viewer sees as flicker beyond the true change of the lighting).
// Prints mean and max over frames, and the seconds per frame of each step; exits 1 when the soft lights' error or
// excess flicker regresses past its bound (kSoftBounds).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "synthetic_room.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/irradiance_map.hpp"
#include "vdrig/probe/object_path.hpp"
#include "vdrig/probe/soft_lights.hpp"

using namespace vdrig;
using namespace vdrig::probe;

namespace {

// The room and its probes: tests/probe_gl/synthetic_room.hpp (shared with test_gpu_fusion and bench_probe_gpu).
const ProxyBox& kRoom = testing::kSyntheticRoom;

Probe render_probe(const Vec3d& position, int height) { return testing::render_room_probe(position, height); }

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct SoftBound {
  const char* method;
  double error_mean, flicker_mean;  // fractions of mean E
};
const SoftBound kSoftBounds[] = {{"soft:16", 0.0119, 0.00072},   // measured 0.790 %, 0.0480 %
                                 {"soft:64", 0.0029, 0.00024}};  // 0.195 %, 0.0161 %

struct Series {
  std::string name;
  std::function<std::vector<Rgb>(const Probe& fused, const std::vector<Vec3d>& normals)> irradiance;
  std::vector<std::vector<Rgb>> frames;
  double seconds = 0;
};

}  // namespace

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 300;
  const int height = 64;
  const std::vector<Vec3d> probe_positions = testing::room_probe_positions();
  std::vector<Probe> probes;
  for (const Vec3d& p : probe_positions) probes.push_back(render_probe(p, height));

  ObjectPath path;
  for (int k = 0; k <= 24; ++k) {
    const double a = 2 * kPi * k / 24;
    path.keys.push_back({a, Vec3d(1300 * std::cos(a), 900 * std::sin(a), 1000 + 250 * std::sin(2 * a))});
  }
  if (Status s = validate_path(path, kRoom, 200); !s.is_ok()) {
    std::fprintf(stderr, "%s\n", s.error().message.c_str());
    return 1;
  }
  const std::vector<Vec3d> positions = sample_path(path, frames);
  const std::vector<Vec3d> normals = fibonacci_directions(64);

  auto evaluate = [](const IrradianceModel& m, const std::vector<Vec3d>& ns) {
    std::vector<Rgb> e;
    for (const Vec3d& n : ns) e.push_back(m.irradiance(n));
    return e;
  };
  auto by_method = [&](const std::string& text) {
    const IrradianceMethodSpec spec = *parse_irradiance_method(text);
    return [spec, evaluate](const Probe& fused, const std::vector<Vec3d>& ns) {
      return evaluate(IrradianceModel::build(fused, spec), ns);
    };
  };
  // Soft lights as points (before issue 28): what spreading them over caps changes.
  auto soft_points = [&](int count) {
    SoftLightOptions o;
    o.count = count;
    o.cap_spread = false;
    return [o](const Probe& fused, const std::vector<Vec3d>& ns) {
      const SoftLights s = soft_lights(fused, o);
      std::vector<Rgb> e;
      for (const Vec3d& n : ns) e.push_back(s.irradiance(n));
      return e;
    };
  };
  std::vector<Series> series = {{"exact", by_method("exact"), {}, 0},
                                {"mediancut:16", by_method("mediancut:16"), {}, 0},
                                {"mediancut:64", by_method("mediancut:64"), {}, 0},
                                {"sh9", by_method("sh9"), {}, 0},
                                {"hybrid:4", by_method("hybrid:4"), {}, 0},
                                {"soft:16", by_method("soft:16"), {}, 0},
                                {"soft:64", by_method("soft:64"), {}, 0},
                                {"soft:16 point", soft_points(16), {}, 0},
                                {"soft:64 point", soft_points(64), {}, 0}};
  FusionOptions options;
  options.height = height;
  double fuse_seconds = 0;
  for (int f = 0; f < frames; ++f) {
    auto t0 = std::chrono::steady_clock::now();
    auto fused = fuse(probes, positions[f], kRoom, options);
    fuse_seconds += seconds_since(t0);
    if (!fused) {
      std::fprintf(stderr, "frame %d: %s\n", f, fused.error().message.c_str());
      return 1;
    }
    for (Series& s : series) {
      t0 = std::chrono::steady_clock::now();
      s.frames.push_back(s.irradiance(*fused, normals));
      s.seconds += seconds_since(t0);
    }
  }
  const auto& truth = series[0].frames;
  std::printf("%d frames, fused %d x %d from %zu probes: %.1f ms per frame\n", frames, 2 * height, height,
              probes.size(), 1e3 * fuse_seconds / frames);
  double true_change = 0;
  for (int f = 1; f < frames; ++f) {
    double d = 0, mean = 0;
    for (size_t n = 0; n < normals.size(); ++n) {
      d += std::abs(luminance(truth[f][n]) - luminance(truth[f - 1][n]));
      mean += luminance(truth[f][n]);
    }
    true_change += d / mean / (frames - 1);
  }
  std::printf("true frame-to-frame change of E: %.3f %% of mean E\n", 100 * true_change);
  bool failed = false;
  std::printf("%-14s %12s %12s %14s %14s %10s\n", "method", "error mean %", "error max %", "flicker mean %",
              "flicker max %", "ms/frame");
  for (const Series& s : series) {
    double err_mean = 0, err_max = 0, fl_mean = 0, fl_max = 0;
    for (int f = 0; f < frames; ++f) {
      double mean = 0, err = 0, fl = 0;
      for (size_t n = 0; n < normals.size(); ++n) {
        const double t = luminance(truth[f][n]), a = luminance(s.frames[f][n]);
        mean += t;
        err += std::abs(a - t);
        if (f > 0) fl += std::abs((a - luminance(s.frames[f - 1][n])) - (t - luminance(truth[f - 1][n])));
      }
      err_mean += err / mean / frames;
      err_max = std::max(err_max, err / mean);
      if (f > 0) {
        fl_mean += fl / mean / (frames - 1);
        fl_max = std::max(fl_max, fl / mean);
      }
    }
    std::printf("%-14s %12.3f %12.3f %14.4f %14.4f %10.2f\n", s.name.c_str(), 100 * err_mean, 100 * err_max,
                100 * fl_mean, 100 * fl_max, 1e3 * s.seconds / frames);
    // The soft lights exist for their stability: their error and excess flicker (mean over the frames, fraction of
    // mean E) must stay within about 1.5x what docs/probe.md shows (300 frames; a shorter run is not checked).
    for (const SoftBound& b : kSoftBounds)
      if (frames == 300 && s.name == b.method && !(err_mean <= b.error_mean && fl_mean <= b.flicker_mean)) {
        std::fprintf(stderr, "REGRESSION: %s error %.3f %% (bound %.3f %%), flicker %.4f %% (bound %.4f %%)\n",
                     b.method, 100 * err_mean, 100 * b.error_mean, 100 * fl_mean, 100 * b.flicker_mean);
        failed = true;
      }
  }
  return failed ? 1 : 0;
}

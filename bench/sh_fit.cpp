// Fitting throughput of the linear per-texel models on whole maps with shared sample directions:
//  - SH-LSOP, 36 coefficients per channel, 512 x 512 texels x 289 directions (target < 20 s on 2 cores);
//  - HSH least squares, 9 coefficients per channel, 256 x 256 texels x 289 directions (target < 2.5 s);
//  - for reference, texels with individual direction sets (ShTexelFitter, Voronoi per texel).
// Values are random (the cost does not depend on them). The map is processed in tiles of 4096 texels, as the
// out-of-core observation map delivers it; one tile buffer is reused, so memory does not grow with the map.
// Usage: bench_sh_fit [threads]   (default 2)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/sh.hpp"

namespace {

using vdrig::Vec3d;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// 17 x 17 pan/tilt grid to +-80 degrees: the rig's usual 289 views.
std::vector<Vec3d> rig_directions() {
  std::vector<Vec3d> dirs;
  for (int i = 0; i < 17; ++i) {
    for (int j = 0; j < 17; ++j) {
      const double pan = vdrig::deg_to_rad(-80.0 + 10.0 * i), tilt = vdrig::deg_to_rad(-80.0 + 10.0 * j);
      dirs.emplace_back(std::cos(tilt) * std::sin(pan), std::sin(tilt), std::cos(tilt) * std::cos(pan));
    }
  }
  return dirs;
}

// Fits texels x 3 channels in tiles; returns seconds for the whole map (operator already built).
double fit_map(const vdrig::fitting::LinearFitOperator& op, int texels, int threads, double* checksum) {
  constexpr int kTileTexels = 4096;
  const int samples = op.sample_count();
  Eigen::MatrixXf values(samples, 3 * kTileTexels);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  for (Eigen::Index i = 0; i < values.size(); ++i) values.data()[i] = u(rng);
  Eigen::MatrixXf coeffs(op.coeff_count(), 3 * kTileTexels);
  double sum = 0.0;
  const auto t0 = Clock::now();
  for (int done = 0; done < texels; done += kTileTexels) {
    const int n = std::min(kTileTexels, texels - done);
    op.apply_batch(values.leftCols(3 * n), coeffs.leftCols(3 * n), threads);
    sum += coeffs(0, 0);  // keep the work observable
  }
  const double s = seconds_since(t0);
  *checksum = sum;
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace vdrig::fitting;
  const int threads = argc > 1 ? std::atoi(argv[1]) : 2;
  const std::vector<Vec3d> dirs = rig_directions();
  bool ok = true;
  double checksum = 0.0;

  // One shared operator (built once: its time counts), applied to every texel of a map side x side.
  auto shared_operator_run = [&](const char* name, const LinearFitOperator& op, double build_s, int side,
                                 double target_s) {
    const int texels = side * side;
    const double fit_s = fit_map(op, texels, threads, &checksum);
    const double total = build_s + fit_s;
    std::printf(
        "%s, %dx%d texels x %zu dirs, %d threads: operator %.3f s, fit %.3f s (%.2f us/texel), total %.3f s  "
        "[target < %g s] %s\n",
        name, side, side, dirs.size(), threads, build_s, fit_s, 1e6 * fit_s / texels, total, target_s,
        total < target_s ? "OK" : "SLOW");
    ok &= total < target_s;
  };
  {
    ShFitOptions options;
    options.bands = 6;
    options.method = ShFitMethod::kLsop;
    const auto t0 = Clock::now();
    const LinearFitOperator op = make_sh_fit_operator(options, dirs);
    shared_operator_run("SH-LSOP 36 coeffs x 3 ch", op, seconds_since(t0), 512, 20.0);
  }
  {
    HshFitOptions options;
    options.bands = 3;
    const auto t0 = Clock::now();
    const LinearFitOperator op = make_hsh_fit_operator(options, dirs);
    shared_operator_run("HSH-LS 9 coeffs x 3 ch", op, seconds_since(t0), 256, 2.5);
  }
  {
    // Individual direction sets: every texel pays its Voronoi partition and basis evaluation (single thread).
    ShFitOptions options;
    options.bands = 6;
    ShTexelFitter fitter(options);
    Eigen::MatrixXd values = Eigen::MatrixXd::Random(static_cast<Eigen::Index>(dirs.size()), 3);
    const int texels = 200;
    const auto t0 = Clock::now();
    for (int t = 0; t < texels; ++t) checksum += fitter.fit(dirs, values)(0, 0);
    const double s = seconds_since(t0);
    std::printf(
        "SH-LSOP 36 coeffs, per-texel directions (%zu each), 1 thread: %.3f ms/texel "
        "(512x512 would take %.0f s)\n",
        dirs.size(), 1e3 * s / texels, s / texels * 512 * 512);
  }
  std::printf("checksum %.3g\n", checksum);
  return ok ? 0 : 1;
}

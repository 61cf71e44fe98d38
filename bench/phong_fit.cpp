// Phong-1 fitting throughput on a whole map: 256 x 256 texels x 289 views (the rig's 17 x 17 pan/tilt grid to
// +-80 degrees, camera at 2500 mm, so every texel has its own directions), through fit_parameter_map on 2 threads
// (target < 60 s). Each texel is a Phong-1 surface with its own Kd, Ks, lobe direction and m (m from 5 to 500,
// log-uniform) plus 1 % multiplicative noise; the recovered parameters are checked loosely so a fast but wrong
// fitter does not pass unnoticed.
// Usage: bench_phong_fit [texels_per_side=256] [threads=2] [model=phong:1]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/phong_model.hpp"

namespace {

using vdrig::Vec3d;
using namespace vdrig::fitting;

vdrig::fitting::PhongParams texel_truth(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PhongParams p;
  p.kd = Vec3d(0.05 + 0.5 * u(rng), 0.05 + 0.5 * u(rng), 0.05 + 0.5 * u(rng));
  PhongLobe l;
  l.ks = Vec3d(0.2 + u(rng), 0.2 + u(rng), 0.2 + u(rng));
  l.direction = vdrig::direction_from_spherical(2 * vdrig::kPi * u(rng), vdrig::deg_to_rad(50.0 * u(rng)));
  l.shininess = 5.0 * std::pow(100.0, u(rng));
  p.lobes.push_back(l);
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  const int side = argc > 1 ? std::atoi(argv[1]) : 256;
  const int threads = argc > 2 ? std::atoi(argv[2]) : 2;
  const std::string model = argc > 3 ? argv[3] : "phong:1";
  constexpr double kSizeMm = 800.0, kDistanceMm = 2500.0;

  std::vector<Vec3d> centres;
  for (int i = 0; i < 17; ++i)
    for (int j = 0; j < 17; ++j) {
      const double pan = vdrig::deg_to_rad(-80.0 + 10.0 * i), tilt = vdrig::deg_to_rad(-80.0 + 10.0 * j);
      centres.push_back(kDistanceMm *
                        Vec3d(std::cos(tilt) * std::sin(pan), std::sin(tilt), std::cos(tilt) * std::cos(pan)));
    }
  ObservationMapSpec spec;
  spec.texels_s = spec.texels_t = side;
  spec.width_mm = spec.height_mm = kSizeMm;
  ObservationMap obs(spec, static_cast<int>(centres.size()));
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<PhongParams> truth(static_cast<size_t>(side) * side);
  for (int t = 0; t < side; ++t)
    for (int s = 0; s < side; ++s) {
      PhongParams& p = truth[static_cast<size_t>(t) * side + s];
      p = texel_truth(rng);
      const Vec3d x = vdrig::texel_centre_mm(s, t, side, side, kSizeMm, kSizeMm);
      for (size_t v = 0; v < centres.size(); ++v) {
        const Vec3d d = (centres[v] - x).normalized();
        const Vec3d rgb = p.evaluate(d) * (1.0 + noise(rng));
        obs.set(s, t, static_cast<int>(v), rgb.cast<float>(), d.cast<float>(), kObsValid);
      }
    }

  MapFitOptions options;
  options.model = parse_model(model).value();
  options.threads = threads;
  const auto t0 = std::chrono::steady_clock::now();
  auto map = fit_parameter_map(obs, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!map) {
    std::fprintf(stderr, "fit failed: %s\n", map.error().describe().c_str());
    return 1;
  }
  // Loose recovery check on the lobe direction and m (noise 1 %, m up to 500).
  int good = 0;
  std::vector<double> angle_err;
  for (int t = 0; t < side; ++t)
    for (int s = 0; s < side; ++s) {
      const PhongParams& p = truth[static_cast<size_t>(t) * side + s];
      const PhongParams f = phong_texel(*map, s, t);
      if (f.lobes.empty()) continue;
      const double a = vdrig::rad_to_deg(vdrig::angle_between(f.lobes[0].direction, p.lobes[0].direction));
      angle_err.push_back(a);
      if (a < 1.0 && std::abs(std::log(f.lobes[0].shininess / p.lobes[0].shininess)) < 0.1) ++good;
    }
  std::sort(angle_err.begin(), angle_err.end());
  const int total = side * side;
  std::printf(
      "%s: %dx%d texels x %zu views, %d threads: %.2f s (%.1f us/texel/thread); lobe within 1 deg and m "
      "within 10 %%: %.1f %% of texels, median direction error %.3f deg\n",
      model.c_str(), side, side, centres.size(), threads, seconds, seconds * 1e6 * threads / total,
      100.0 * good / total, angle_err.empty() ? 0.0 : angle_err[angle_err.size() / 2]);
  // Side by side in one process: the default solver against Ceres (autodiff, one residual block per texel) on the
  // same texels, one thread each.
  if (model == "phong:1") {
    const int sample = std::min(total, 2048);
    double seconds_by_solver[2] = {0, 0};
    double worst_angle_between_solvers = 0.0;
    std::vector<PhongParams> direct(sample);
    for (int solver = 0; solver < 2; ++solver) {
      PhongFitOptions po;
      po.solver = solver == 0 ? PhongSolver::kDirect : PhongSolver::kCeres;
      const auto s0 = std::chrono::steady_clock::now();
      for (int i = 0; i < sample; ++i) {
        const PhongFit f = fit_phong(obs.texel(i % side, i / side), po);
        if (solver == 0)
          direct[i] = f.params;
        else if (!f.params.lobes.empty() && !direct[i].lobes.empty())
          worst_angle_between_solvers = std::max(
              worst_angle_between_solvers,
              vdrig::rad_to_deg(vdrig::angle_between(f.params.lobes[0].direction, direct[i].lobes[0].direction)));
      }
      seconds_by_solver[solver] = std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
    }
    std::printf(
        "phong:1 solver side by side, %d texels, 1 thread: direct %.3f ms/texel, Ceres %.3f ms/texel (Ceres / direct "
        "= %.2f); largest lobe-direction difference %.4f deg\n",
        sample, 1e3 * seconds_by_solver[0] / sample, 1e3 * seconds_by_solver[1] / sample,
        seconds_by_solver[1] / seconds_by_solver[0], worst_angle_between_solvers);
  }
  return 0;
}

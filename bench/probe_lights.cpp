// Median cut (64 and 256 lights) and SH-9 projection on the three real probes of tests/data/probes (1024 x 512):
// time per call (best of several runs) and irradiance accuracy against brute-force integration over the full map
// at 1024 Fibonacci normals (mean and max relative error of the luminance irradiance, and mean |dE| / mean E).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "vdrig/probe/irradiance_error.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/sh_irradiance.hpp"
#include "vdrig/test/build_paths.hpp"

using namespace vdrig;
using namespace vdrig::probe;

namespace {

double best_seconds(int runs, const std::function<void()>& f) {
  double best = 1e300;
  for (int r = 0; r < runs; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

}  // namespace

int main() {
  const std::filesystem::path dir = std::filesystem::path(VDRIG_TEST_DATA_DIR) / "probes";
  const auto normals = fibonacci_directions(1024);
  std::printf("%-10s %-16s %10s %10s %10s %12s\n", "probe", "method", "time ms", "E mean %", "E max %",
              "|dE|/E mean %");
  for (const char* name : {"courtyard", "interior", "studio"}) {
    auto loaded = load_probe(dir / (std::string(name) + ".exr"));
    if (!loaded) {
      std::fprintf(stderr, "%s\n", loaded.error().describe().c_str());
      return 1;
    }
    const Probe& p = *loaded;
    const IrradianceIntegrator brute(p);
    std::vector<Rgb> ref;
    const double brute_s = best_seconds(1, [&] {
      ref.clear();
      for (const auto& n : normals) ref.push_back(brute.irradiance(n));
    });
    std::printf("%-10s %-16s %10.3f %10s %10s %12s\n", name, "brute E(n)", 1e3 * brute_s / normals.size(), "-", "-",
                "-");
    for (int count : {64, 256}) {
      std::vector<DirectionalLight> lights;
      const double s = best_seconds(5, [&] { lights = median_cut(p, count); });
      const auto e = irradiance_error(
          normals, [&](const Vec3d& n) { return irradiance_from_lights(lights, n); }, ref);
      std::printf("%-10s %-16s %10.2f %10.2f %10.2f %12.2f\n", name, (std::to_string(count) + " lights").c_str(),
                  1e3 * s, 100 * e.mean, 100 * e.max, 100 * e.of_mean);
    }
    Sh9 sh;
    const double s = best_seconds(5, [&] { sh = project_sh9(p); });
    const auto e = irradiance_error(
        normals, [&](const Vec3d& n) { return sh9_irradiance(sh, n); }, ref);
    std::printf("%-10s %-16s %10.2f %10.2f %10.2f %12.2f\n", name, "SH-9 projection", 1e3 * s, 100 * e.mean,
                100 * e.max, 100 * e.of_mean);
  }
  std::printf("(brute E(n): ms per normal over the full map; times are the best of 5 runs, one thread)\n");
  return 0;
}

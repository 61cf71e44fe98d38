// The glTF export rendered by a peer: three.js (npm three, pinned in tests/gltf/package-lock.json; its GLTFLoader and
// WebGLRenderer) in Debian's headless chromium (tests/gltf/three_render.mjs, puppeteer-core as tests/web's browser
// test). A simulated bumped GGX sample is observed from icosahedron:3@85 through the 8-bit camera, fitted with
// ggx:iso+n, exported, and rendered by three.js from held-out views (directions not in the scheme, perspective cameras
// whose pose and field of view the test also ray-casts) under the session's point light. Each pixel on the sample is
// compared with the simulator's radiance there (the "photograph") and with the fitted map's own radiance (the model
// vdrig renders, ParameterMap::evaluate at the pixel's texel), as region means in 8-bit codes (the view's brightest
// true pixel at 220 codes), 4 x 4 regions. The same views rendered with the normal map's green channel negated must
// be far worse: the test would see a wrong tangent convention. Skips (CTest's skip code) without chromium, node or
// tests/gltf's node_modules (scripts/setup: npm ci).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "../fitting/rig_observations.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/gltf_export.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/texel_recording.hpp"
#include "vdrig/test/browser.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;
using Json = nlohmann::json;

/// glTF's frame (Y up) from the surface frame (z up): (x, y, z) -> (x, z, -y); and back.
Vec3d to_gltf(const Vec3d& s) { return {s.x(), s.z(), -s.y()}; }
Vec3d from_gltf(const Vec3d& g) { return {g.x(), -g.z(), g.y()}; }

struct View {
  Vec3d eye_m;  // surface frame, metres
  double fov_y_deg;
};

/// Per-region mean differences in codes of one view: worst and mean over the regions that hold pixels.
struct RegionDiff {
  double worst = 0, mean = 0;
};

constexpr int kSize = 96, kRegions = 4;

TEST(GltfThree, RendersTheExportLikeTheFitAndThePhotographs) {
  const std::string chromium = test::find_chromium();
  const fs::path folder = fs::path(VDRIG_SOURCE_DIR) / "tests" / "gltf";
  if (chromium.empty()) GTEST_SKIP() << "no chromium (scripts/setup installs it)";
  if (!fs::exists("/usr/bin/node") || !fs::exists(folder / "node_modules" / "three" / "package.json") ||
      !fs::exists(folder / "node_modules" / "puppeteer-core" / "package.json"))
    GTEST_SKIP() << "node or tests/gltf's node_modules missing (scripts/setup: npm ci in tests/gltf)";

  // The sample: the `bands` surface (1 x 1 m, one point light) of one bumped GGX plastic, 24 x 24 texels.
  sim::Scene scene = sim::make_scene("bands").value();
  sim::Material plastic{"plastic", Vec3d(0.6, 0.25, 0.1)};
  plastic.kind = sim::MaterialKind::kGgx;
  plastic.roughness = 0.2;
  plastic.f0 = Vec3d::Constant(0.04);
  plastic.bump_slope = 0.3;
  plastic.bump_period_mm = 400.0;
  scene.materials = {plastic};
  scene.patches.clear();
  scene.markers.clear();
  const int S = 24;
  const std::vector<Vec3d> scheme = fitting::test_support::scheme_directions("icosahedron:3@85");
  fitting::ObservationMap obs({S, S, scene.width_mm, scene.height_mm}, static_cast<int>(scheme.size()));
  for (int t = 0; t < S; ++t)
    for (int s = 0; s < S; ++s) {
      fitting::TexelObservations texel = fitting::test_support::observe_texel(
          scene, texel_centre_mm(s, t, S, S, scene.width_mm, scene.height_mm), scheme);
      sim::record_texel(texel.radiance, {}, 9000u + static_cast<unsigned>(t * S + s));
      for (size_t v = 0; v < texel.size(); ++v)
        obs.set(s, t, static_cast<int>(v), texel.radiance[v], texel.direction[v], fitting::kObsValid);
    }
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("ggx:iso+n").value();
  options.threads = 2;
  const fitting::SessionLight light = session_light_of(scene).value();
  options.model_options.edit<fitting::GgxFitOptions>().light = light;
  auto map = fitting::fit_parameter_map(obs, options);
  ASSERT_TRUE(map) << map.error().describe();
  test::TempDir dir("gltf_three");
  auto written = export_gltf(*map, dir / "export", "bumped");
  ASSERT_TRUE(written) << written.error().describe();

  // Held-out views: none is a scheme direction (the nearest is several degrees away), one near the light's mirror
  // direction (the highlight), 2.5 m from the sample's centre.
  auto eye = [](double zenith_deg, double azimuth_deg) -> Vec3d {
    return 2.5 * direction_from_spherical(deg_to_rad(azimuth_deg), deg_to_rad(zenith_deg));
  };
  const std::vector<View> views = {{eye(33.0, 217.0), 28.0}, {eye(52.0, 100.0), 28.0}, {eye(18.0, 301.0), 28.0}};
  Json job;
  job["gltf"] = written->gltf.string();
  job["width"] = kSize;
  job["height"] = kSize;
  job["light"] = {
      {"position", {to_gltf(light.position_m).x(), to_gltf(light.position_m).y(), to_gltf(light.position_m).z()}},
      // three.js's point light: irradiance intensity cos / d^2 times its BRDF (albedo / pi); vdrig's I
      // lights a white Lambertian to radiance I / d^2: a factor pi.
      {"intensity", {kPi * light.intensity.x(), kPi * light.intensity.y(), kPi * light.intensity.z()}}};
  job["views"] = Json::array();
  for (bool flip : {false, true})
    for (const View& v : views) {
      const Vec3d e = to_gltf(v.eye_m);
      job["views"].push_back({{"position", {e.x(), e.y(), e.z()}},
                              {"target", {0, 0, 0}},
                              {"up", {0, 0, -1}},
                              {"fov_y_deg", v.fov_y_deg},
                              {"flip_green", flip}});
    }
  {
    std::ofstream out(dir / "job.json");
    out << job.dump();
  }
  const auto start = std::chrono::steady_clock::now();
  const test::ProcessRun run = test::run_process({"/usr/bin/node", (folder / "three_render.mjs").string(), chromium,
                                                  (dir / "profile").string(), (dir / "job.json").string()},
                                                 {.timeout_s = 120});
  const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const Json result = Json::parse(run.out);
  std::printf("three.js r%s (%.1f s for %zu views): %s\n", result["info"]["revision"].get<std::string>().c_str(),
              render_s, job["views"].size(), result["info"].dump().c_str());

  std::vector<RegionDiff> three_truth, map_truth, three_map;
  std::vector<Vec3d> ratios;
  for (size_t k = 0; k < job["views"].size(); ++k) {
    const View& v = views[k % views.size()];
    const std::vector<float> pixels = result["views"][k].get<std::vector<float>>();
    ASSERT_EQ(pixels.size(), static_cast<size_t>(kSize * kSize * 4));
    // The camera as three.js's lookAt builds it: z from the target to the eye, x = up x z, y = z x x (glTF frame).
    const Vec3d e = to_gltf(v.eye_m), zc = e.normalized();
    const Vec3d up(0, 0, -1);
    const Vec3d xc = up.cross(zc).normalized();
    const Vec3d yc = zc.cross(xc);
    const double tan_half = std::tan(deg_to_rad(v.fov_y_deg) / 2.0);
    constexpr int kCells = kRegions * kRegions;
    std::vector<Vec3d> sum_three(kCells, Vec3d::Zero()), sum_truth(kCells, Vec3d::Zero()),
        sum_map(kCells, Vec3d::Zero());
    std::vector<int> count(kCells, 0);
    double brightest = 0;
    Vec3d total_three = Vec3d::Zero(), total_truth = Vec3d::Zero();
    for (int j = 0; j < kSize; ++j)  // j = 0: the bottom row (readRenderTargetPixels)
      for (int i = 0; i < kSize; ++i) {
        const double x = (2.0 * (i + 0.5) / kSize - 1.0) * tan_half, y = (2.0 * (j + 0.5) / kSize - 1.0) * tan_half;
        Vec3d ray = x * xc;
        ray += y * yc;
        ray -= zc;
        ray.normalize();
        if (ray.y() >= 0) continue;
        const Vec3d hit = e + ray * (-e.y() / ray.y());
        const Vec3d p_mm = 1000.0 * from_gltf(hit);
        // Whole pixels inside the sample, away from its edge (texture clamping, partial pixels).
        const double margin = 0.02 * scene.width_mm;
        if (std::abs(p_mm.x()) > scene.width_mm / 2 - margin || std::abs(p_mm.y()) > scene.height_mm / 2 - margin)
          continue;
        const Vec3d to_eye = (v.eye_m * 1000.0 - p_mm).normalized();
        const Vec3d truth = scene.radiance(Vec3d(p_mm.x(), p_mm.y(), 0.0), to_eye);
        const int s = std::clamp(static_cast<int>((p_mm.x() / scene.width_mm + 0.5) * S), 0, S - 1);
        const int t = std::clamp(static_cast<int>((p_mm.y() / scene.height_mm + 0.5) * S), 0, S - 1);
        const Vec3d fitted = map->evaluate(s, t, to_eye);
        const size_t at = 4 * (static_cast<size_t>(j) * kSize + static_cast<size_t>(i));
        const Vec3d three(pixels[at], pixels[at + 1], pixels[at + 2]);
        const int ri = std::clamp(static_cast<int>((p_mm.x() / scene.width_mm + 0.5) * kRegions), 0, kRegions - 1);
        const int rj = std::clamp(static_cast<int>((p_mm.y() / scene.height_mm + 0.5) * kRegions), 0, kRegions - 1);
        const size_t cell = static_cast<size_t>(ri * kRegions + rj);
        sum_three[cell] += three, sum_truth[cell] += truth, sum_map[cell] += fitted;
        ++count[cell];
        brightest = std::max(brightest, truth.maxCoeff());
        total_three += three, total_truth += truth;
      }
    ASSERT_GT(brightest, 0.0);
    const double codes = 220.0 / brightest;
    RegionDiff d3t, dmt, d3m;
    int regions = 0;
    for (size_t cell = 0; cell < static_cast<size_t>(kCells); ++cell) {
      if (count[cell] < 20) continue;
      ++regions;
      const double n = count[cell];
      const Vec3d ta = (sum_three[cell] - sum_truth[cell]) / n, tb = (sum_map[cell] - sum_truth[cell]) / n,
                  tc = (sum_three[cell] - sum_map[cell]) / n;
      const double a = codes * ta.cwiseAbs().maxCoeff(), b = codes * tb.cwiseAbs().maxCoeff(),
                   c = codes * tc.cwiseAbs().maxCoeff();
      d3t.worst = std::max(d3t.worst, a), d3t.mean += a;
      dmt.worst = std::max(dmt.worst, b), dmt.mean += b;
      d3m.worst = std::max(d3m.worst, c), d3m.mean += c;
    }
    ASSERT_GE(regions, 12) << "view " << k << " sees too little of the sample";
    for (RegionDiff* r : {&d3t, &dmt, &d3m}) r->mean /= regions;
    std::printf(
        "view %zu%s: region mean |difference| in codes (worst / mean over %d regions): three.js vs photo %.2f / %.2f, "
        "fit vs photo %.2f / %.2f, three.js vs fit %.2f / %.2f\n",
        k % views.size(), k >= views.size() ? " (green negated)" : "", regions, d3t.worst, d3t.mean, dmt.worst,
        dmt.mean, d3m.worst, d3m.mean);
    const Vec3d ratio = total_three.cwiseQuotient(total_truth);
    std::printf("  three.js / photo over the sample: %.4f %.4f %.4f (R G B)\n", ratio.x(), ratio.y(), ratio.z());
    three_truth.push_back(d3t), map_truth.push_back(dmt), three_map.push_back(d3m), ratios.push_back(ratio);
  }
  // Measured (docs/results.md, section 9): three.js vs photo 3.46 / 7.12 / 5.02 codes worst region, 2.62 / 5.10 /
  // 3.63 mean; the fit vs photo 0.53 / 0.41 / 0.63; three.js vs the fit 3.34 / 7.30 / 5.54. three.js renders the sample
  // 0.4-4.2 % darker than the photographs over all (green 0.9956 / 0.9618 / 0.9655): glTF's dielectric weights the
  // diffuse by 1 - F, vdrig's and the simulator's do not (docs/models.md). Negating the normal map's green channel
  // makes the worst region 1.99-7.8 times worse (12.6-26.9 codes).
  for (size_t k = 0; k < views.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_LT(three_truth[k].worst, 10.7);
    EXPECT_LT(three_truth[k].mean, 7.7);
    EXPECT_LT(three_map[k].worst, 11.0);
    EXPECT_LT(map_truth[k].worst, 0.95);
    EXPECT_GT(ratios[k].minCoeff(), 0.94);
    EXPECT_LT(ratios[k].maxCoeff(), 1.027);
    // The other tangent-space convention (green negated) is far from the photographs: the test sees the convention.
    EXPECT_GT(three_truth[k + views.size()].worst, 1.5 * three_truth[k].worst);
  }
}

}  // namespace
}  // namespace vdrig::pipeline

// The glTF export rendered by a second peer: Blender imports it with its own glTF importer
// (bpy.ops.import_scene.gltf, the io_scene_gltf2 add-on Debian's blender ships) and renders it with Cycles
// (tests/gltf/blender_render.py) from the held-out views of the three.js test (tests/pipeline/test_gltf_three.cpp)
// under a point light of the session's intensity. Sample, views and comparison are those of the three.js test
// (tests/pipeline/gltf_views.hpp): per 4 x 4 region in 8-bit codes, Blender vs the simulator's radiance ("photo"),
// the fit vs the photo, Blender vs the fit. The same views with the normal map's green channel negated must be far
// worse: the test sees a wrong tangent convention. The same views with Principled BSDF's Fresnel taken out hold the
// cause of the highlight view's excess. Skipped when Blender is not installed (or its Python lacks numpy,
// which the importer needs).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "../pipeline/gltf_views.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;
using Json = nlohmann::json;
using namespace gltf_views;

TEST(GltfBlender, RendersTheExportLikeTheFitAndThePhotographs) {
  if (!fs::exists("/usr/bin/blender")) GTEST_SKIP() << "no blender (scripts/setup installs it)";
  const FittedSample sample = fit_bumped_plastic();
  ASSERT_TRUE(sample.map);
  test::TempDir dir("gltf_blender");
  auto written = export_gltf(*sample.map, dir / "export", "bumped");
  ASSERT_TRUE(written) << written.error().describe();

  const std::vector<View> views = held_out_views();
  const Vec3d& intensity = sample.light.intensity;
  Json job;
  job["gltf"] = written->gltf.string();
  job["width"] = kSize;
  job["height"] = kSize;
  job["samples"] = 16;
  job["out_dir"] = dir.path().string();
  // Cycles' point light of power P W lights a white Lambertian at d m to radiance P / (4 pi^2 d^2)
  // (sim/blender/vdrig_blender.py); vdrig's I to I / d^2.
  job["light"] = {{"position", {sample.light.position_m.x(), sample.light.position_m.y(), sample.light.position_m.z()}},
                  {"power_w", 4 * kPi * kPi * intensity.maxCoeff()},
                  {"colour",
                   {intensity.x() / intensity.maxCoeff(), intensity.y() / intensity.maxCoeff(),
                    intensity.z() / intensity.maxCoeff()}}};
  job["views"] = Json::array();
  // Views 0-2 as imported, 3-5 with the green negated, 6-8 with Principled's Fresnel taken out (fresnel_free).
  for (int variant : {0, 1, 2})
    for (const View& v : views) {
      // Blender's frame is the surface frame: the three.js camera's axes taken back from glTF's frame.
      const CameraAxes a = camera_axes(v);
      const Vec3d x = from_gltf(a.x), y = from_gltf(a.y), z = from_gltf(a.z);
      job["views"].push_back({{"camera_to_world",
                               {x.x(), y.x(), z.x(), v.eye_m.x(), x.y(), y.y(), z.y(), v.eye_m.y(), x.z(), y.z(), z.z(),
                                v.eye_m.z(), 0, 0, 0, 1}},
                              {"fov_y_deg", v.fov_y_deg},
                              {"flip_green", variant == 1},
                              {"fresnel_free", variant == 2}});
    }
  {
    std::ofstream out(dir / "job.json");
    out << job.dump();
  }
  const fs::path script = fs::path(VDRIG_SOURCE_DIR) / "tests" / "gltf" / "blender_render.py";
  const auto start = std::chrono::steady_clock::now();
  const test::ProcessRun run = test::run_process({"/usr/bin/blender", "--background", "--factory-startup", "--python",
                                                  script.string(), "--", (dir / "job.json").string()},
                                                 {.timeout_s = 240});
  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (run.exit_code == 3 && run.out.find("VDRIG_SKIP") != std::string::npos) GTEST_SKIP() << run.out;
  ASSERT_EQ(run.exit_code, 0) << run.err << run.out;
  const size_t at = run.out.find("VDRIG_RESULT ");
  ASSERT_NE(at, std::string::npos) << run.out;
  const Json facts = Json::parse(run.out.substr(at + 13, run.out.find('\n', at) - at - 13));
  std::printf("Blender (%.1f s in all, %.1f s rendering %zu views): %s\n", total_s, facts["render_s"].get<double>(),
              job["views"].size(), facts.dump().c_str());

  std::vector<ViewComparison> compared;
  for (size_t k = 0; k < job["views"].size(); ++k) {
    std::vector<float> pixels(static_cast<size_t>(kSize * kSize * 4));
    std::ifstream in(dir / ("view_" + std::to_string(k) + ".f32"), std::ios::binary);
    in.read(reinterpret_cast<char*>(pixels.data()), static_cast<std::streamsize>(pixels.size() * sizeof(float)));
    ASSERT_TRUE(in) << "view " << k << ": no image";
    compared.push_back(compare_view(sample, views[k % views.size()], pixels));
    if (k >= 2 * views.size()) std::printf("Principled's Fresnel taken out (Diffuse + Glossy GGX of 0.04):\n");
    print_comparison("Blender", k % views.size(), k >= views.size() && k < 2 * views.size(), compared.back());
  }
  // Measured (docs/results.md, section 9): Blender vs photo 6.73 / 2.09 / 1.61 codes worst region, 2.82 / 0.71 /
  // 0.57 mean; the fit vs photo 0.53 / 0.41 / 0.63; Blender vs the fit 6.63 / 2.27 / 2.18. Over the sample Blender is
  // within 0.5 % of the photographs on views 1 and 2 (Principled BSDF does not weight the diffuse by 1 - F, as
  // three.js does) and 2.0 / 4.6 / 7.6 % brighter (R G B) on view 0, the highlight's: a stronger white lobe. Negating
  // the normal map's green channel makes the worst region 3.5-7.1 times worse (11.4-23.8 codes).
  const double worst[] = {6.73, 2.09, 1.61}, mean[] = {2.82, 0.71, 0.57};
  for (size_t k = 0; k < views.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_LT(compared[k].peer_truth.worst, 1.5 * worst[k]);
    EXPECT_LT(compared[k].peer_truth.mean, 1.5 * mean[k]);
    EXPECT_LT(compared[k].map_truth.worst, 0.95);
    EXPECT_GT(compared[k].ratio.minCoeff(), 0.993);
    EXPECT_LT(compared[k].ratio.maxCoeff(), 1.115);
    // The other tangent-space convention (green negated) is far from the photographs: the test sees the convention.
    EXPECT_GT(compared[k + views.size()].peer_truth.worst, 2.0 * compared[k].peer_truth.worst);
  }
  // The cause of view 0's excess (docs/results.md section 9): Principled v1's Fresnel, the exact dielectric one of
  // IOR 1.5 rescaled to F0 (12 % above Schlick's at the highlight's half-angle, 40 deg at the centre). Without it
  // (Lambert + a Glossy GGX of colour 0.04) Blender / photo is 0.994 / 0.997 / 0.997 on view 0, worst region 2.15
  // codes (from 6.73); 0.993-0.996 on views 1 and 2.
  const ViewComparison& free0 = compared[2 * views.size()];
  EXPECT_LT(free0.peer_truth.worst, 1.5 * 2.15);
  EXPECT_GT(free0.ratio.minCoeff(), 0.985);
  EXPECT_LT(free0.ratio.maxCoeff(), 1.01);
  EXPECT_GT(compared[0].ratio.z() - free0.ratio.z(), 0.05);
}

}  // namespace
}  // namespace vdrig::pipeline

// The glTF round trip (issue #29): a Blender Principled material (scripts/blender_scenes.py's bumped_textured_plastic,
// noise-textured base colour, roughness 0.4, specular 0.5, a bump map) captured through the "blender" camera, fitted
// with ggx:iso+n under the .blend's light, exported with `vdrig export --format gltf`'s export_gltf, imported back into
// Blender with its own glTF importer and rendered with Cycles from the held-out views' camera poses; compared with the
// ORIGINAL .blend rendered from the same poses by the same Cycles (tests/fidelity/blender_roundtrip.py), and beside
// vdrig's own render of the fit (ParameterMap::evaluate at each pixel's texel). Calibration is the simulator's truth
// (write_true_calibration): the calibration chain on Blender images is fidelity_test_blender_session's. The
// comparison, as tests/pipeline/gltf_views.hpp's: per 4 x 4 region of the 0.8 x 0.8 m sample, the region mean
// |difference| in 8-bit codes (220 codes = the original view's 99.5th percentile pixel), worst and mean over the
// regions. A negative control: the imported roughness squared (the exporter writing alpha where glTF wants
// sqrt(alpha)) must be far worse. Figures and bounds: docs/blender.md, docs/results.md section 9. Skipped when
// Blender is not installed or its Python lacks numpy.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "blender_session.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/gltf_export.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;
using Json = nlohmann::json;

using test_blender::since_s;

constexpr int kRegions = 4;
constexpr double kSampleHalfM = 0.4;  // the .blend's sample: the central 0.8 x 0.8 m of the 1 m board

struct RegionDiff {
  double worst = 0, mean = 0;
};

/// One held-out view, each image against the original: Blender's import, vdrig's render of the fit, the control, the
/// import with the specular conversion corrected (when rendered); and the import against vdrig's render. Totals over
/// the sample / the original's (R G B).
struct RoundTrip {
  RegionDiff gltf, fit, control, corrected, gltf_fit;
  Vec3d gltf_ratio = Vec3d::Zero(), fit_ratio = Vec3d::Zero(), corrected_ratio = Vec3d::Zero();
  int regions = 0;
};

std::vector<float> read_f32(const fs::path& file, size_t count) {
  std::vector<float> pixels(count);
  std::ifstream in(file, std::ios::binary);
  in.read(reinterpret_cast<char*>(pixels.data()), static_cast<std::streamsize>(count * sizeof(float)));
  if (!in) pixels.clear();
  return pixels;
}

/// `images`: Blender's original, import, control and corrected renders (the last may be empty), RGBA, bottom row
/// first.
RoundTrip compare(const CameraModel& cam, const ViewPose& pose, const fitting::ParameterMap& map,
                  const std::array<std::vector<float>, 4>& images) {
  RoundTrip out;
  const Vec3d centre_mm = pose.camera_centre();
  constexpr int kCells = kRegions * kRegions;
  enum { kOriginal, kGltf, kControl, kCorrected, kFit, kKinds };
  const bool corrected = !images[kCorrected].empty();
  std::vector<std::array<Vec3d, kKinds>> sums(kCells);
  for (auto& s : sums) s.fill(Vec3d::Zero());
  std::vector<int> count(kCells, 0);
  std::vector<double> levels;
  std::array<Vec3d, kKinds> total;
  total.fill(Vec3d::Zero());
  // Whole texels of the sample, away from its edge (the observation map's texels there mix sample and board).
  const double margin_m = 0.04;
  for (int row = 0; row < cam.height; ++row)  // row 0: the image's top (OpenCV); Blender's buffer is bottom first
    for (int col = 0; col < cam.width; ++col) {
      // R^T: the camera axes in the surface frame (no Mat3d copy of it: GCC 12 -Wmaybe-uninitialized in Eigen).
      const Vec3d ray = pose.R.transpose() * Vec3d((col - cam.cx) / cam.fx, (row - cam.cy) / cam.fy, 1.0);
      if (ray.z() >= 0) continue;
      const Vec3d hit_mm = centre_mm + ray * (-centre_mm.z() / ray.z());
      if (std::abs(hit_mm.x()) > 1000 * (kSampleHalfM - margin_m) ||
          std::abs(hit_mm.y()) > 1000 * (kSampleHalfM - margin_m))
        continue;
      const int s =
          std::clamp(static_cast<int>((hit_mm.x() / map.width_mm() + 0.5) * map.texels_s()), 0, map.texels_s() - 1);
      const int t =
          std::clamp(static_cast<int>((hit_mm.y() / map.height_mm() + 0.5) * map.texels_t()), 0, map.texels_t() - 1);
      const size_t at = 4 * (static_cast<size_t>(cam.height - 1 - row) * cam.width + static_cast<size_t>(col));
      std::array<Vec3d, kKinds> v;
      v.fill(Vec3d::Zero());
      for (int k = 0; k < kFit; ++k)
        v[k] =
            k == kCorrected && !corrected ? Vec3d::Zero() : Vec3d(images[k][at], images[k][at + 1], images[k][at + 2]);
      v[kFit] = map.evaluate(s, t, (centre_mm - hit_mm).normalized());
      const int ri =
          std::clamp(static_cast<int>((hit_mm.x() / 1000 / (2 * kSampleHalfM) + 0.5) * kRegions), 0, kRegions - 1);
      const int rj =
          std::clamp(static_cast<int>((hit_mm.y() / 1000 / (2 * kSampleHalfM) + 0.5) * kRegions), 0, kRegions - 1);
      const size_t cell = static_cast<size_t>(ri * kRegions + rj);
      for (int k = 0; k < kKinds; ++k) sums[cell][k] += v[k], total[k] += v[k];
      ++count[cell];
      levels.push_back(v[kOriginal].maxCoeff());
    }
  EXPECT_GT(levels.size(), 2000u) << "the view sees too little of the sample";
  if (levels.empty()) return out;
  const size_t p = levels.size() * 995 / 1000;
  std::nth_element(levels.begin(), levels.begin() + static_cast<std::ptrdiff_t>(p), levels.end());
  const double codes = 220.0 / levels[p];
  const auto add = [&](RegionDiff& r, const Vec3d& a, const Vec3d& b, double n) {
    const double d = codes * ((a - b) / n).cwiseAbs().maxCoeff();
    r.worst = std::max(r.worst, d), r.mean += d;
  };
  for (size_t cell = 0; cell < static_cast<size_t>(kCells); ++cell) {
    if (count[cell] < 20) continue;
    ++out.regions;
    const auto& c = sums[cell];
    add(out.gltf, c[kGltf], c[kOriginal], count[cell]);
    add(out.fit, c[kFit], c[kOriginal], count[cell]);
    add(out.control, c[kControl], c[kOriginal], count[cell]);
    if (corrected) add(out.corrected, c[kCorrected], c[kOriginal], count[cell]);
    add(out.gltf_fit, c[kGltf], c[kFit], count[cell]);
  }
  EXPECT_GE(out.regions, 12) << "the view sees too little of the sample";
  if (out.regions > 0)
    for (RegionDiff* r : {&out.gltf, &out.fit, &out.control, &out.corrected, &out.gltf_fit}) r->mean /= out.regions;
  out.gltf_ratio = total[kGltf].cwiseQuotient(total[kOriginal]);
  out.fit_ratio = total[kFit].cwiseQuotient(total[kOriginal]);
  out.corrected_ratio = total[kCorrected].cwiseQuotient(total[kOriginal]);
  return out;
}

TEST(BlenderRoundTrip, ReimportedExportMatchesTheOriginalRenders) {
  if (!fs::exists("/usr/bin/blender")) GTEST_SKIP() << "no blender (scripts/setup installs it)";
  const test::TempDir dir("blender_roundtrip");
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path blend = test_blender::make_sample_blend(dir.path(), "bumped_textured_plastic", "/usr/bin/blender");
  ASSERT_TRUE(fs::exists(blend));

  // A latlong:4 session (53 views) at 256 x 192, the demo's field of view, lens distortion on, Cycles 16 samples a
  // pixel, three exposures; no markers (the poses are the truth's).
  CaptureRequest req = test_blender::blender_capture_request(dir.path() / "session", blend, "latlong:4");
  req.rig_config["camera"]["executable"] = "/usr/bin/blender";
  req.rig_config["camera"]["markers"] = false;
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_EQ(session->completed_view_count(), n);
  const double capture_s = since_s(t0);
  ASSERT_TRUE(vdrig::test::write_true_calibration(session.value()));
  ASSERT_TRUE(merge_session_hdr(session.value()));

  // ggx:iso+n at 64 x 64 texels (16 mm) under the .blend's light (patchwork's, as blender_table's --light-scene).
  FitRequest request;
  request.model = "ggx:iso+n";
  request.holdout = 3;
  request.light_scene = "patchwork";
  request.threads = 2;
  auto options = fit_options_for(request, n);
  ASSERT_TRUE(options) << options.error().describe();
  auto geometry = session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();
  // Held out: two views spread over the session (spread_holdout_views) and the one nearest the light's mirror
  // direction at the sample's centre, the highlight's view.
  const auto& light = options->model_options.get<fitting::GgxFitOptions>().light;
  ASSERT_TRUE(light.has_value());
  const Vec3d light_mm = 1000.0 * light->position_m;
  const Vec3d mirror(-light_mm.x(), -light_mm.y(), light_mm.z());
  int highlight = 0;
  for (int v = 0; v < n; ++v)
    if (geometry->poses[static_cast<size_t>(v)].camera_centre().normalized().dot(mirror.normalized()) >
        geometry->poses[static_cast<size_t>(highlight)].camera_centre().normalized().dot(mirror.normalized()))
      highlight = v;
  std::vector<int> held_out = {highlight};
  for (int v : spread_holdout_views(n, 3))
    if (held_out.size() < 3 && v != highlight) held_out.push_back(v);
  options->held_out = held_out;
  std::sort(options->held_out.begin(), options->held_out.end());
  auto obs_path = session_obsmap_file(session.value(), 64, 64);
  ASSERT_TRUE(obs_path) << obs_path.error().describe();
  auto obs = fitting::ObsMapReader::open(obs_path.value());
  ASSERT_TRUE(obs) << obs.error().describe();
  const auto t_fit = std::chrono::steady_clock::now();
  auto map = fitting::fit_parameter_map(obs.value(), options.value());
  ASSERT_TRUE(map) << map.error().describe();
  const double fit_s = since_s(t_fit);
  auto written = export_gltf(map.value(), dir.path() / "export", "roundtrip");
  ASSERT_TRUE(written) << written.error().describe();

  const auto sc = sim::SimConfig::from_json(req.rig_config["sim"]);
  ASSERT_TRUE(sc);
  // The comparison's camera: the session's intrinsics without the lens distortion (both renders share it).
  CameraModel cam = sc->camera;
  Json job = {{"blend", blend.string()},
              {"gltf", written->gltf.string()},
              {"out_dir", dir.path().string()},
              {"width", cam.width},
              {"height", cam.height},
              {"fx", cam.fx},
              {"cx", cam.cx},
              {"cy", cam.cy},
              {"samples", 16}};
  job["views"] = Json::array();
  ASSERT_EQ(held_out.size(), 3u);
  for (int index : held_out) {
    const ViewPose& pose = geometry->poses[static_cast<size_t>(index)];
    const Vec3d centre_m = pose.camera_centre() / 1000.0;
    Json m = Json::array();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) m.push_back(pose.R(c, r));  // R^T, the camera axes as columns
      m.push_back(centre_m[r]);
    }
    for (double v : {0.0, 0.0, 0.0, 1.0}) m.push_back(v);
    job["views"].push_back(m);
  }
  {
    std::ofstream out(dir / "job.json");
    out << job.dump();
  }
  const fs::path script = fs::path(VDRIG_SOURCE_DIR) / "tests" / "fidelity" / "blender_roundtrip.py";
  const auto t_blender = std::chrono::steady_clock::now();
  const test::ProcessRun run = test::run_process({"/usr/bin/blender", "--background", "--factory-startup", "--python",
                                                  script.string(), "--", (dir / "job.json").string()},
                                                 {.timeout_s = 240});
  const double blender_s = since_s(t_blender);
  if (run.exit_code == 3 && run.out.find("VDRIG_SKIP") != std::string::npos) GTEST_SKIP() << run.out;
  ASSERT_EQ(run.exit_code, 0) << run.err << run.out;
  ASSERT_NE(run.out.find("VDRIG_RESULT "), std::string::npos) << run.out;
  std::printf("%d views (capture %.1f s), ggx:iso+n 64 x 64 fit %.1f s, Blender round trip %.1f s, all %.1f s\n", n,
              capture_s, fit_s, blender_s, since_s(t0));

  const size_t count = static_cast<size_t>(cam.width * cam.height * 4);
  std::vector<RoundTrip> results;
  for (size_t k = 0; k < held_out.size(); ++k) {
    const auto name = [&](const char* prefix) { return dir / (prefix + ("_" + std::to_string(k)) + ".f32"); };
    const std::array<std::vector<float>, 4> images = {read_f32(name("original"), count), read_f32(name("gltf"), count),
                                                      read_f32(name("control"), count),
                                                      read_f32(name("corrected"), count)};
    ASSERT_FALSE(images[0].empty() || images[1].empty() || images[2].empty()) << "view " << k << ": no image";
    const RoundTrip r = compare(cam, geometry->poses[static_cast<size_t>(held_out[k])], map.value(), images);
    const Vec3d eye = geometry->poses[static_cast<size_t>(held_out[k])].camera_centre().normalized();
    std::printf(
        "held-out view %d (zenith %.0f deg, azimuth %.0f deg): region |difference| in codes, worst / mean over %d "
        "regions: Blender's "
        "import vs original %.2f / %.2f, vdrig's fit vs original %.2f / %.2f, import vs fit %.2f / %.2f, control "
        "(roughness squared) vs original %.2f / %.2f\n",
        held_out[k], rad_to_deg(std::acos(eye.z())), rad_to_deg(std::atan2(eye.y(), eye.x())), r.regions, r.gltf.worst,
        r.gltf.mean, r.fit.worst, r.fit.mean, r.gltf_fit.worst, r.gltf_fit.mean, r.control.worst, r.control.mean);
    std::printf("  specular conversion corrected vs original %.2f / %.2f\n", r.corrected.worst, r.corrected.mean);
    std::printf("  over the sample, / original: import %.4f %.4f %.4f, fit %.4f %.4f %.4f, corrected %.4f %.4f %.4f\n",
                r.gltf_ratio.x(), r.gltf_ratio.y(), r.gltf_ratio.z(), r.fit_ratio.x(), r.fit_ratio.y(), r.fit_ratio.z(),
                r.corrected_ratio.x(), r.corrected_ratio.y(), r.corrected_ratio.z());
    results.push_back(r);
  }
  // Measured (docs/blender.md, docs/results.md section 9), views in the order highlight, then two spread: Blender's
  // import vs the original 20.7 / 5.30 / 0.94 codes worst region, 5.74 / 1.72 / 0.48 mean; vdrig's render of the fit
  // 6.11 / 1.43 / 0.75 and 1.67 / 0.53 / 0.59 (over the sample the fit is within 0.5 % of the original on the held-out
  // highlight); the import with its specular conversion replaced by glTF's definition 19.8 / 4.91 / 1.04 and 5.87 /
  // 1.74 / 0.49. Before the observation map dropped grazing samples (kObsCoarse, 2026-12-05) the fit took the 80 deg
  // ring's blends of neighbouring patches as the texel's own and was 18 % too bright on the highlight: import 116.8 /
  // 7.85 / 2.17 worst, fit 99.4 / 6.07 / 1.44. The control (roughness squared) 274 / 30.8 / 7.42 worst, 50.7 / 12.2 /
  // 4.01 mean.
  const double gltf_worst[] = {20.7, 5.30, 0.94}, gltf_mean[] = {5.74, 1.72, 0.48};
  const double fit_worst[] = {6.11, 1.43, 0.75}, fit_mean[] = {1.67, 0.53, 0.59};
  const double corrected_worst[] = {19.8, 4.91, 1.04};
  ASSERT_TRUE(written->specular_extension) << "the fit's F0 is 0.04 everywhere: the experiment needs the extension";
  int control_fails = 0;
  for (size_t k = 0; k < results.size(); ++k) {
    SCOPED_TRACE(k);
    const RoundTrip& r = results[k];
    EXPECT_LT(r.gltf.worst, 1.5 * gltf_worst[k]);
    EXPECT_LT(r.gltf.mean, 1.5 * gltf_mean[k]);
    EXPECT_LT(r.fit.worst, 1.5 * fit_worst[k]);
    EXPECT_LT(r.fit.mean, 1.5 * fit_mean[k]);
    EXPECT_LT(r.corrected.worst, 1.5 * corrected_worst[k]);
    // Blender's own import reads the specular as the extension defines it: as close to the original as the node tree
    // rewired to the definition (an 8-bit sRGB texture, read undecoded, was twice as far on the highlight view).
    EXPECT_LT(std::abs(r.gltf.mean - r.corrected.mean), 0.1 * r.corrected.mean);
    if (r.control.worst > 1.5 * gltf_worst[k] || r.control.mean > 1.5 * gltf_mean[k]) ++control_fails;
  }
  // The roughness squared fails the bounds on every view: the highlight's 13 times the import's worst, the third 7.9.
  EXPECT_GT(results[0].control.worst, 3.0 * gltf_worst[0]);
  EXPECT_EQ(control_fails, 3);
}

}  // namespace
}  // namespace vdrig::pipeline

// Adaptive sampling against uniform schemes (issue 30, docs/sampling.md "adaptive", docs/results.md): per scene,
// sessions captured on the simulator with adaptive:N and with uniform schemes (spiral, latlong, icosahedron) of about
// the same size, and the uniform 289-view icosahedron:3@85 as the reference; each session's HDR views merged, a
// 32x32 observation map, a phong:1 fit, and the fit evaluated against the simulator's truth (pipeline::evaluate_map:
// relative RMS over 1000 directions, texel-weighted mean over the materials but printed paper, and the worst one).
// Times: the stage's moves (capture/route.hpp's move model) from home through every view in capture order, beside the
// same views routed at once (a lower bound no loop can reach: later batches depend on earlier views); rig time = the
// moves + the shooting (what the simulated rig charges a view: the bracket's exposures, 0.5 + 0.125 + 0.03 s; it
// models no readout or settle) + the adaptive planner's wall time between batches (the rig waits for it).
// Held-out photographs (`vdrig compare`, pipeline::compare_maps): per scene a separate session of 12 views
// (stratified:3x4:97@80, in none of the schemes) is captured once and each fitted map is rendered there and compared
// with its HDR photographs: mean |render - photo| in 8-bit codes over all counted pixels, what a real rig (no truth)
// can measure. Needs OpenGL (xvfb-run); "n/a" without.
// --blender: a Blender session (docs/blender.md) too, on scripts/blender_scenes.py's glossy_plastic (one Principled
// BSDF) at 160x120, 16 samples a pixel: no truth there, so only the held-out photographs; skipped when blender is
// not on PATH.
//
// The sessions' calib/ is the simulator's truth (write_true_calibration): this measures where the views are, not the
// calibration. The adaptive planner projects with the true intrinsics too (camera=...).
//
// Usage: bench_adaptive_sampling [work_dir] [--scenes a,b] [--schemes s1;s2] [--blender] [--blender-only]
//   (work_dir default /tmp/vdrig_bench_adaptive; scenes: patchwork, ggx4, lights2; prints one table per scene)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "vdrig/capture/adaptive.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/route.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/pipeline/adaptive_stage.hpp"
#include "vdrig/pipeline/compare_stage.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/hdr_stage.hpp"
#include "vdrig/pipeline/obsmap_stage.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace {
using namespace vdrig;
namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kTexels = 32;

/// A GGX scene: four patches of GGX materials (rough to glossy, dielectric and metal) under one point light.
fs::path write_ggx_scene(const fs::path& dir) {
  json materials = json::array();
  materials.push_back({{"name", "ggx r0.08 metal"},
                       {"kind", "ggx"},
                       {"kd", {0.02, 0.02, 0.02}},
                       {"roughness", 0.08},
                       {"f0", {0.9, 0.8, 0.6}}});
  materials.push_back({{"name", "ggx r0.15 plastic"},
                       {"kind", "ggx"},
                       {"kd", {0.1, 0.25, 0.5}},
                       {"roughness", 0.15},
                       {"f0", {0.04, 0.04, 0.04}}});
  materials.push_back({{"name", "ggx r0.3 plastic"},
                       {"kind", "ggx"},
                       {"kd", {0.5, 0.2, 0.1}},
                       {"roughness", 0.3},
                       {"f0", {0.04, 0.04, 0.04}}});
  materials.push_back({{"name", "ggx r0.5 metal"},
                       {"kind", "ggx"},
                       {"kd", {0.02, 0.02, 0.02}},
                       {"roughness", 0.5},
                       {"f0", {0.6, 0.6, 0.65}}});
  materials.push_back({{"name", "marker black"}, {"kd", {0.02, 0.02, 0.02}}});
  json patches = json::array();
  const double x[3] = {-400, -25, 400};
  int m = 0;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      patches.push_back({{"x0_mm", x[i] + (i ? 50 : 0)},
                         {"y0_mm", x[j] + (j ? 50 : 0)},
                         {"x1_mm", x[i + 1]},
                         {"y1_mm", x[j + 1]},
                         {"material", m++}});
  json markers = json::array();
  for (const auto& c : {std::pair{-450.0, -450.0}, {450.0, -450.0}, {450.0, 450.0}, {-450.0, 450.0}})
    markers.push_back({{"centre_mm", {c.first, c.second}}, {"radius_mm", 30.0}, {"material", 4}});
  const json scene = {{"format", "vdrig-scene"},
                      {"version", 1},
                      {"name", "ggx4"},
                      {"width_mm", 1000.0},
                      {"height_mm", 1000.0},
                      {"materials", materials},
                      {"patches", patches},
                      {"markers", markers},
                      {"lights", {{{"position_mm", {1500.0, 1500.0, 2000.0}}, {"intensity", {1.5e7, 1.5e7, 1.5e7}}}}}};
  const fs::path path = dir / "ggx4.json";
  std::ofstream(path) << scene.dump(2);
  return path;
}

json rig_config(const std::string& scene, const std::string& blend = "") {
  json rc = sim::sim_rig_config({{"scene", scene},
                                 {"samples_per_axis", 1},
                                 {"camera",
                                  {{"width", blend.empty() ? 200 : 160},
                                   {"height", blend.empty() ? 150 : 120},
                                   {"fx", blend.empty() ? 300 : 240},
                                   {"fy", blend.empty() ? 300 : 240},
                                   {"cx", blend.empty() ? 99.5 : 79.5},
                                   {"cy", blend.empty() ? 74.5 : 59.5},
                                   {"k1", 0},
                                   {"k2", 0}}}});
  if (!blend.empty()) rc["camera"] = {{"backend", "blender"}, {"samples", 16}, {"threads", 2}, {"blend", blend}};
  return rc;
}

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(sep, start), text.size());
    if (end > start) out.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

struct Row {
  std::string scheme;
  int views = 0;
  double move_s = 0;
  double global_move_s = 0;   // the same views routed at once from home
  double shoot_s = 0;         // the bracket's exposures over every frame
  double plan_s = 0;          // the adaptive planner's wall time
  double compare_codes = -1;  // mean |render - photo| at the held-out photographs, 8-bit codes (-1: not measured)
  double mean_rel = 0;
  double worst_rel = 0;
  std::string worst_material;
  double seconds = 0;
  std::string stopped;
};

Result<capture::Session> capture_session(const fs::path& dir, const json& rc, const std::string& scheme,
                                         const fs::path& camera_yml, const sim::Scene& scene) {
  fs::remove_all(dir);
  auto rig = sim::simulator_and_hardware_backends().make_rig(rc);
  if (!rig) return rig.error();
  capture::PlanRequest req;
  req.rig_config = rc;
  req.scheme = capture::is_adaptive_scheme(scheme) ? scheme + ",camera=" + camera_yml.string() : scheme;
  req.bracket = "fixed:0.5,0.125,0.03";
  req.stage = rig->stage->spec();
  req.surface_width_mm = scene.width_mm;
  req.surface_height_mm = scene.height_mm;
  auto manifest =
      capture::is_adaptive_scheme(scheme) ? capture::plan_adaptive_manifest(req) : capture::plan_manifest(req);
  if (!manifest) return manifest.error();
  auto session = capture::Session::create(dir, manifest.value());
  if (!session) return session.error();
  VDRIG_TRY(session->lock());
  capture::CaptureOptions options;
  options.bracket = capture::parse_bracket(req.bracket).value();
  options.disk_reserve_bytes = 0;
  if (capture::is_adaptive_scheme(scheme)) {
    auto planner = pipeline::make_coarse_fit_planner();
    capture::AdaptiveOptions adaptive;
    adaptive.capture = options;
    VDRIG_TRY(capture::run_adaptive_session(rig.value(), session.value(), *planner, adaptive));
  } else {
    VDRIG_TRY(capture::run_session(rig.value(), session.value(), options));
  }
  return session;
}

/// The held-out photographs of a scene: a session of its own, merged, calibrated with the truth.
Result<capture::Session> held_out_session(const fs::path& dir, const json& rc, const sim::Scene& scene) {
  auto session = capture_session(dir, rc, "stratified:3x4:97@80", {}, scene);
  if (!session) return session.error();
  VDRIG_TRY(vdrig::test::write_true_calibration(session.value()));
  auto merged = pipeline::merge_session_hdr(session.value());
  if (!merged) return merged.error();
  return session;
}

Result<Row> measure(const fs::path& dir, const json& rc, const std::string& scheme, const fs::path& camera_yml,
                    const capture::Session* held_out, bool truth) {
  const auto t0 = std::chrono::steady_clock::now();
  auto scene_r = sim::make_scene(rc["sim"]["scene"].get<std::string>());
  if (!scene_r) return scene_r.error();
  const sim::Scene& scene = scene_r.value();
  auto session = capture_session(dir, rc, scheme, camera_yml, scene);
  if (!session) return session.error();
  auto rig = sim::simulator_and_hardware_backends().make_rig(rc);
  if (!rig) return rig.error();
  Row row;
  row.scheme = scheme;
  if (capture::is_adaptive_scheme(scheme)) {
    const auto progress = capture::adaptive_progress(session.value());
    row.stopped = progress.stopped.value_or("");
    for (const auto& b : progress.batches) row.plan_s += b.info.value("planning_s", 0.0);
  }
  std::vector<PanTilt> targets;
  for (const auto& v : session->manifest().views) {
    targets.push_back(v.target);
    for (const auto& f : session->frames_of_view(v.index)) row.shoot_s += f.exposure_s;
  }
  row.global_move_s = capture::plan_route(rig->stage->spec(), PanTilt{0, 0}, targets).planned_time_s;
  PanTilt at{0, 0};
  for (const auto& v : session->manifest().views) {
    row.move_s += capture::move_time_s(rig->stage->spec(), at, v.target);
    at = v.target;
  }
  row.views = static_cast<int>(session->manifest().views.size());
  VDRIG_TRY(vdrig::test::write_true_calibration(session.value()));
  auto merged = pipeline::merge_session_hdr(session.value());
  if (!merged) return merged.error();
  auto obs = pipeline::build_session_obsmap(session.value(), kTexels, kTexels);
  if (!obs) return obs.error();
  fitting::MapFitOptions fit;
  fit.threads = 2;
  auto map = fitting::fit_parameter_map(obs.value(), fit);
  if (!map) return map.error();
  if (held_out) {
    const fs::path map_file = dir.parent_path() / "map.exr";
    VDRIG_TRY(map->write(map_file));
    pipeline::CompareOptions co;
    co.out_dir = dir.parent_path() / "compare";
    std::vector<int> views;
    for (const auto& v : held_out->manifest().views) views.push_back(v.index);
    auto compared = pipeline::compare_maps(*held_out, {map_file}, views, co);
    if (compared) {
      double sum = 0;
      long long n = 0;
      for (const auto& r : compared->rows) {
        sum += r.all.mean * static_cast<double>(r.all.samples);
        n += r.all.samples;
      }
      row.compare_codes = n ? sum / static_cast<double>(n) : -1;
    } else {
      std::fprintf(stderr, "compare %s: %s\n", scheme.c_str(), compared.error().describe().c_str());
    }
  }
  row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!truth) {
    fs::remove_all(dir);
    return row;
  }
  auto report = pipeline::evaluate_map(map.value(), scene, {});
  if (!report) return report.error();
  double sum = 0;
  int texels = 0;
  for (const auto& m : report->materials) {
    // The markers, and printed paper whose print is finer than a 32x32 texel (no sampling fixes that), left out.
    if (m.name == "marker black" || m.name.find("printed") != std::string::npos || !std::isfinite(m.dense.mean))
      continue;
    sum += m.dense.mean * m.texels;
    texels += m.texels;
    if (m.dense.mean > row.worst_rel) {
      row.worst_rel = m.dense.mean;
      row.worst_material = m.name;
    }
  }
  row.mean_rel = texels ? sum / texels : 0;
  row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  fs::remove_all(dir);
  return row;
}

void print_header(bool truth) {
  std::printf(
      "| scheme | views | moves s | same views routed at once s | shooting s | planning s | rig time s |%s"
      " held-out photos: mean abs. codes | bench s | stopped |\n",
      truth ? " mean rel. RMS | worst material (rel. RMS) |" : "");
  std::printf("|---|---|---|---|---|---|---|%s---|---|---|\n", truth ? "---|---|" : "");
}

void print_row(const Row& r, bool truth) {
  std::printf("| `%s` | %d | %.1f | %.1f | %.1f | %.1f | %.1f |", r.scheme.c_str(), r.views, r.move_s, r.global_move_s,
              r.shoot_s, r.plan_s, r.move_s + r.shoot_s + r.plan_s);
  if (truth) std::printf(" %.4f | %s (%.4f) |", r.mean_rel, r.worst_material.c_str(), r.worst_rel);
  if (r.compare_codes >= 0)
    std::printf(" %.2f |", r.compare_codes);
  else
    std::printf(" n/a |");
  std::printf(" %.0f | %s |\n", r.seconds, r.stopped.c_str());
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  fs::path work = "/tmp/vdrig_bench_adaptive";
  std::vector<std::string> scene_names = {"patchwork", "ggx4", "lights2"};
  // ahead=1: each batch planned and routed alone (the loop before the joint route), for comparison.
  std::vector<std::string> schemes = {"adaptive:30,ahead=1", "adaptive:30",     "spiral:30:3@85", "latlong:4:85",
                                      "adaptive:60,ahead=1", "adaptive:60",     "spiral:60:5@85", "icosahedron:2@85",
                                      "spiral:120:7@85",     "icosahedron:3@85"};
  std::vector<std::string> blender_schemes = {"adaptive:60,ahead=1", "adaptive:60", "spiral:60:5@85",
                                              "icosahedron:3@85"};
  bool blender = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--scenes" && i + 1 < argc) {
      scene_names = split(argv[++i], ',');
    } else if (arg == "--schemes" && i + 1 < argc) {
      schemes = blender_schemes = split(argv[++i], ';');
    } else if (arg == "--blender") {
      blender = true;
    } else if (arg == "--blender-only") {
      blender = true;
      scene_names.clear();
    } else {
      work = arg;
    }
  }
  fs::create_directories(work);
  (void)log::set_level("warn");
  const CameraModel camera{200, 150, 300.0, 300.0, 99.5, 74.5, 0, 0, 0, 0, 0};
  const fs::path camera_yml = work / "camera.yml";
  if (!camera.save_yaml(camera_yml)) return 1;
  for (const auto& name : scene_names) {
    const std::string scene = name == "ggx4" ? write_ggx_scene(work).string() : name;
    const json rc = rig_config(scene);
    auto scene_r = sim::make_scene(scene);
    if (!scene_r) return 1;
    auto held_out = held_out_session(work / "held_out", rc, scene_r.value());
    if (!held_out) std::fprintf(stderr, "held-out session: %s\n", held_out.error().describe().c_str());
    std::printf("\nscene %s: phong:1 at %dx%d texels, relative RMS vs the truth over 1000 directions\n", name.c_str(),
                kTexels, kTexels);
    print_header(true);
    for (const auto& scheme : schemes) {
      auto row = measure(work / "session", rc, scheme, camera_yml, held_out ? &held_out.value() : nullptr, true);
      if (!row) {
        std::printf("| %s | failed: %s |\n", scheme.c_str(), row.error().describe().c_str());
        continue;
      }
      print_row(row.value(), true);
    }
  }
  if (blender) {
    if (std::system("command -v blender >/dev/null 2>&1") != 0) {
      std::printf("\nblender: not on PATH, skipped\n");
      return 0;
    }
    const fs::path blend = work / "glossy_plastic.blend";
    const std::string make = "blender --background --factory-startup --python " +
                             (fs::path(VDRIG_SOURCE_DIR) / "scripts" / "blender_scenes.py").string() + " -- " +
                             work.string() + " glossy_plastic >/dev/null 2>&1";
    if (std::system(make.c_str()) != 0 || !fs::exists(blend)) {
      std::printf("\nblender: could not write %s\n", blend.c_str());
      return 1;
    }
    const CameraModel small{160, 120, 240.0, 240.0, 79.5, 59.5, 0, 0, 0, 0, 0};
    const fs::path small_yml = work / "camera_160.yml";
    if (!small.save_yaml(small_yml)) return 1;
    const json rc = rig_config("patchwork", blend.string());
    auto scene_r = sim::make_scene("patchwork");  // the surface size and markers the .blend is captured with
    if (!scene_r) return 1;
    auto held_out = held_out_session(work / "held_out", rc, scene_r.value());
    if (!held_out) std::fprintf(stderr, "held-out session: %s\n", held_out.error().describe().c_str());
    std::printf(
        "\nBlender session (Cycles, glossy_plastic.blend, 160x120, 16 samples): phong:1 at %dx%d texels, no "
        "truth\n",
        kTexels, kTexels);
    print_header(false);
    for (const auto& scheme : blender_schemes) {
      auto row = measure(work / "session", rc, scheme, small_yml, held_out ? &held_out.value() : nullptr, false);
      if (!row) {
        std::printf("| %s | failed: %s |\n", scheme.c_str(), row.error().describe().c_str());
        continue;
      }
      print_row(row.value(), false);
    }
  }
  return 0;
}

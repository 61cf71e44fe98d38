// Adaptive sampling against uniform schemes (issue 30, docs/sampling.md "adaptive", docs/results.md): per scene,
// sessions captured on the simulator with adaptive:N and with uniform schemes (spiral, latlong, icosahedron) of about
// the same size, and the uniform 289-view icosahedron:3@85 as the reference; each session's HDR views merged, a
// 32x32 observation map, a phong:1 fit, and the fit evaluated against the simulator's truth (pipeline::evaluate_map:
// relative RMS over 1000 directions, texel-weighted mean over the materials but printed paper, and the worst one).
// Rig time: the stage's planned moves (capture/route.hpp's move model) from home through every view in capture order.
//
// The sessions' calib/ is the simulator's truth (write_true_calibration): this measures where the views are, not the
// calibration. The adaptive planner projects with the true intrinsics too (camera=...).
//
// Usage: bench_adaptive_sampling [work_dir] [--scenes patchwork,ggx4,lights2] [--schemes "adaptive:60;spiral:60:5@85"]
//        [--fits "phong:1,phong:1 sa,ggx:iso"] [--diagnose]
// (default /tmp/vdrig_bench_adaptive, every scene and scheme, phong:1; prints one table per scene). --fits fits each
// session with each model (" sa": solid-angle weights, PhongFitOptions::solid_angle_weights; ggx with the scene's one
// light, skipped on a scene lit otherwise); --diagnose adds per material where the error is (cone, grazing, else).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "vdrig/capture/adaptive.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/route.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/pipeline/adaptive_stage.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
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

json rig_config(const std::string& scene) {
  return sim::sim_rig_config({{"scene", scene},
                              {"samples_per_axis", 1},
                              {"camera",
                               {{"width", 200},
                                {"height", 150},
                                {"fx", 300},
                                {"fy", 300},
                                {"cx", 99.5},
                                {"cy", 74.5},
                                {"k1", 0},
                                {"k2", 0}}}});
}

/// One fit of a captured session: the figures of the bench's table.
struct FitRow {
  std::string fit;  // what was fitted, e.g. "phong:1" or "phong:1 sa" (solid-angle weights)
  double mean_rel = 0;
  double mean_smooth_rel = 0;  // the same without brushed metal, whose bumps are finer than a texel (noisy: +-0.05)
  double worst_rel = 0;
  std::string worst_material;
  std::string diagnosis;  // --diagnose: per material, where the error is
};

struct Row {
  std::string scheme;
  int views = 0;
  double move_s = 0;
  std::vector<FitRow> fits;
  double seconds = 0;
  std::string stopped;
};

/// How a session is fitted: the model, with or without solid-angle (Voronoi) weights.
struct FitVariant {
  std::string model = "phong:1";
  bool solid_angle = false;
  std::string label() const { return model + (solid_angle ? " sa" : ""); }
};

struct BenchOptions {
  std::vector<FitVariant> fits = {FitVariant{}};
  bool diagnose = false;
};

/// --diagnose: per material, the relative RMS split by direction (sqrt(err^2 in the class / truth^2 over all), so the
/// squares of the three add up to the material's): in a 20 deg cone around a light's mirror direction, grazing
/// (zenith > 60 deg, outside the cones), elsewhere; and the strongest lobe's axis error against the mirror direction
/// of the scene's first light (mean over the material's texels, deg).
std::string diagnose(const fitting::ParameterMap& map, const sim::Scene& scene, const pipeline::EvalReport& report) {
  const auto dirs = pipeline::hemisphere_directions(1000);
  const int S = map.texels_s(), T = map.texels_t();
  struct Acc {
    double err2[3] = {0, 0, 0}, truth2 = 0, axis_deg = 0;
    int axis_n = 0;
  };
  std::vector<Acc> acc(scene.materials.size());
  const double cone_cos = std::cos(20.0 * kPi / 180.0);
  for (int t = 0; t < T; ++t)
    for (int s = 0; s < S; ++s) {
      const Vec3d p = texel_centre_mm(s, t, S, T, map.width_mm(), map.height_mm());
      // Whole texels on one material only (as evaluate_map's statistics).
      const double hx = 0.5 * map.width_mm() / S, hy = 0.5 * map.height_mm() / T;
      const int m = scene.material_at(p.x(), p.y());
      if (m < 0 || m != scene.material_at(p.x() - hx, p.y() - hy) || m != scene.material_at(p.x() + hx, p.y() + hy))
        continue;
      std::vector<Vec3d> mirrors;
      for (const auto& l : scene.lights) {
        const Vec3d to = (l.position_mm - p).normalized();
        mirrors.emplace_back(-to.x(), -to.y(), to.z());
      }
      Acc& a = acc[static_cast<size_t>(m)];
      for (const Vec3d& v : dirs) {
        const Vec3d truth = scene.radiance(p, v), fit = map.evaluate(s, t, v);
        bool cone = false;
        for (const auto& r : mirrors) cone = cone || v.dot(r) >= cone_cos;
        const int cls = cone ? 0 : v.z() < 0.5 ? 1 : 2;
        a.err2[cls] += (fit - truth).squaredNorm();
        a.truth2 += truth.squaredNorm();
      }
      const auto lobes = map.model().lobes(map.parameters(s, t));
      if (!lobes.empty() && !mirrors.empty()) {
        const auto strongest = std::max_element(lobes.begin(), lobes.end(), [](const auto& x, const auto& y) {
          return x.peak_rgb.sum() < y.peak_rgb.sum();
        });
        a.axis_deg += std::acos(std::clamp(strongest->direction.dot(mirrors.front()), -1.0, 1.0)) * 180.0 / kPi;
        ++a.axis_n;
      }
    }
  std::string out;
  for (const auto& me : report.materials) {
    if (me.name == "marker black" || me.name.find("printed") != std::string::npos) continue;
    size_t m = 0;
    while (m < scene.materials.size() && scene.materials[m].name != me.name) ++m;
    if (m == scene.materials.size() || acc[m].truth2 <= 0) continue;
    const Acc& a = acc[m];
    char line[320];
    std::snprintf(line, sizeof line, "    %-22s rel %.4f | cone %.4f grazing %.4f else %.4f | axis %5.1f deg (%d)",
                  me.name.c_str(), me.dense.mean, std::sqrt(a.err2[0] / a.truth2), std::sqrt(a.err2[1] / a.truth2),
                  std::sqrt(a.err2[2] / a.truth2), a.axis_n ? a.axis_deg / a.axis_n : 0.0, a.axis_n);
    out += line;
    if (me.has_phong) {
      std::snprintf(line, sizeof line, " | kd %.3f ks %.3f m %.3f", me.phong.kd_rel, me.phong.ks_rel,
                    me.phong.shininess_rel);
      out += line;
    }
    out += "\n";
  }
  return out;
}

Result<FitRow> fit_and_evaluate(const fitting::ObservationMap& obs, const sim::Scene& scene, const FitVariant& variant,
                                bool with_diagnosis) {
  fitting::MapFitOptions fit;
  fit.threads = 2;
  auto model = fitting::parse_model(variant.model);
  if (!model) return model.error();
  fit.model = model.value();
  if (variant.model.rfind("ggx", 0) == 0) {
    auto light = pipeline::session_light_of(scene);
    if (!light) return light.error();
    fit.model_options.edit<fitting::GgxFitOptions>().light = light.value();
  }
  if (variant.solid_angle) fit.model_options.edit<fitting::PhongFitOptions>().solid_angle_weights = true;
  auto map = fitting::fit_parameter_map(obs, fit);
  if (!map) return map.error();
  auto report = pipeline::evaluate_map(map.value(), scene, {});
  if (!report) return report.error();
  FitRow row;
  row.fit = variant.label();
  double sum = 0, smooth_sum = 0;
  int texels = 0, smooth_texels = 0;
  for (const auto& m : report->materials) {
    // The markers, and printed paper whose print is finer than a 32x32 texel (no sampling fixes that), left out.
    if (m.name == "marker black" || m.name.find("printed") != std::string::npos || !std::isfinite(m.dense.mean))
      continue;
    sum += m.dense.mean * m.texels;
    texels += m.texels;
    if (m.name.find("brushed") == std::string::npos) {
      smooth_sum += m.dense.mean * m.texels;
      smooth_texels += m.texels;
    }
    if (m.dense.mean > row.worst_rel) {
      row.worst_rel = m.dense.mean;
      row.worst_material = m.name;
    }
  }
  row.mean_rel = texels ? sum / texels : 0;
  row.mean_smooth_rel = smooth_texels ? smooth_sum / smooth_texels : 0;
  if (with_diagnosis) row.diagnosis = diagnose(map.value(), scene, report.value());
  return row;
}

Result<Row> measure(const fs::path& dir, const json& rc, const std::string& scheme, const fs::path& camera_yml,
                    const BenchOptions& bench) {
  const auto t0 = std::chrono::steady_clock::now();
  fs::remove_all(dir);
  auto rig = sim::simulator_and_hardware_backends().make_rig(rc);
  if (!rig) return rig.error();
  capture::PlanRequest req;
  req.rig_config = rc;
  req.scheme = capture::is_adaptive_scheme(scheme) ? scheme + ",camera=" + camera_yml.string() : scheme;
  req.bracket = "fixed:0.5,0.125,0.03";
  req.stage = rig->stage->spec();
  auto scene_r = sim::make_scene(rc["sim"]["scene"].get<std::string>());
  if (!scene_r) return scene_r.error();
  const sim::Scene& scene = scene_r.value();
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
  Row row;
  row.scheme = scheme;
  if (capture::is_adaptive_scheme(scheme)) {
    auto planner = pipeline::make_coarse_fit_planner();
    capture::AdaptiveOptions adaptive;
    adaptive.capture = options;
    VDRIG_TRY(capture::run_adaptive_session(rig.value(), session.value(), *planner, adaptive));
    row.stopped = capture::adaptive_progress(session.value()).stopped.value_or("");
  } else {
    VDRIG_TRY(capture::run_session(rig.value(), session.value(), options));
  }
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
  for (const auto& variant : bench.fits) {
    // A BRDF model needs the scene's one point light: not on a scene lit otherwise (lights2).
    if (variant.model.rfind("ggx", 0) == 0 && !pipeline::session_light_of(scene)) continue;
    auto fit = fit_and_evaluate(obs.value(), scene, variant, bench.diagnose);
    if (!fit) return fit.error();
    row.fits.push_back(fit.value());
  }
  row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  fs::remove_all(dir);
  return row;
}

std::vector<std::string> split_commas(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    if (comma > start) out.push_back(text.substr(start, comma - start));
    start = comma + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  fs::path work = "/tmp/vdrig_bench_adaptive";
  std::vector<std::string> scene_names = {"patchwork", "ggx4", "lights2"};
  std::vector<std::string> schemes = {"adaptive:30",  "adaptive:60",      "spiral:30:3@85",  "spiral:60:5@85",
                                      "latlong:4:85", "icosahedron:2@85", "spiral:120:7@85", "icosahedron:3@85"};
  BenchOptions bench;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--scenes" && has_value) {
      scene_names = split_commas(argv[++i]);
    } else if (arg == "--schemes" && has_value) {
      // ';'-separated: a scheme may hold commas (adaptive:60,batch=6).
      schemes.clear();
      std::string list = argv[++i];
      for (size_t a = 0, b; a <= list.size(); a = b + 1) {
        b = std::min(list.find(';', a), list.size());
        if (b > a) schemes.push_back(list.substr(a, b - a));
      }
    } else if (arg == "--fits" && has_value) {
      // e.g. "phong:1,phong:1 sa,ggx:iso": each session fitted so (" sa": solid-angle weights).
      bench.fits.clear();
      for (const auto& f : split_commas(argv[++i])) {
        FitVariant v;
        v.solid_angle = f.size() > 3 && f.substr(f.size() - 3) == " sa";
        v.model = v.solid_angle ? f.substr(0, f.size() - 3) : f;
        bench.fits.push_back(v);
      }
    } else if (arg == "--diagnose") {
      bench.diagnose = true;
    } else if (arg.rfind("--", 0) != 0) {
      work = arg;
    } else {
      std::fprintf(stderr,
                   "usage: bench_adaptive_sampling [work_dir] [--scenes a,b] [--schemes \"s1;s2\"] "
                   "[--fits \"phong:1,phong:1 sa,ggx:iso\"] [--diagnose]\n");
      return 2;
    }
  }
  fs::create_directories(work);
  (void)log::set_level("warn");
  const CameraModel camera{200, 150, 300.0, 300.0, 99.5, 74.5, 0, 0, 0, 0, 0};
  const fs::path camera_yml = work / "camera.yml";
  if (!camera.save_yaml(camera_yml)) return 1;
  for (auto scene : scene_names) {
    if (scene == "ggx4") scene = write_ggx_scene(work).string();
    std::printf("\nscene %s: at %dx%d texels, relative RMS vs the truth over 1000 directions\n",
                fs::path(scene).stem().c_str(), kTexels, kTexels);
    std::printf(
        "| scheme | views | rig moves (s) | fit | mean rel. RMS | mean, no brushed metal | worst material (rel. RMS) "
        "| bench s | stopped |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& scheme : schemes) {
      auto row = measure(work / "session", rig_config(scene), scheme, camera_yml, bench);
      if (!row) {
        std::printf("| %s | failed: %s |\n", scheme.c_str(), row.error().describe().c_str());
        continue;
      }
      for (const auto& f : row->fits) {
        std::printf("| `%s` | %d | %.1f | %s | %.4f | %.4f | %s (%.4f) | %.0f | %s |\n", scheme.c_str(), row->views,
                    row->move_s, f.fit.c_str(), f.mean_rel, f.mean_smooth_rel, f.worst_material.c_str(), f.worst_rel,
                    row->seconds, row->stopped.c_str());
        if (!f.diagnosis.empty()) std::printf("%s", f.diagnosis.c_str());
      }
      std::fflush(stdout);
    }
  }
  return 0;
}

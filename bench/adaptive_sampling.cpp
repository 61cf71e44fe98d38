// Adaptive sampling against uniform schemes (issue 30, docs/sampling.md "adaptive", docs/results.md): per scene,
// sessions captured on the simulator with adaptive:N and with uniform schemes (spiral, latlong, icosahedron) of about
// the same size, and the uniform 289-view icosahedron:3@85 as the reference; each session's HDR views merged, a
// 32x32 observation map, the fits of --fits (phong:1 by default), and each fit evaluated against the simulator's truth
// (pipeline::evaluate_map: relative RMS over 1000 directions, texel-weighted mean over the materials but printed paper,
// and the worst one). Times: the stage's moves (capture/route.hpp's move model) from home through every view in capture
// order, beside the same views routed at once (a lower bound no loop can reach: later batches depend on earlier views);
// rig time = the moves + the shooting (what the simulated rig charges a view: the bracket's exposures, 0.5 + 0.125 +
// 0.03 s; it models no readout or settle) + the adaptive planner's wall time between batches (the rig waits for it).
// Held-out photographs (`vdrig compare`, pipeline::compare_maps): per scene a separate session of 12 views
// (stratified:3x4:97@80, in none of the schemes) is captured once and each fitted map is rendered there and compared
// with its HDR photographs: mean |render - photo| in 8-bit codes over all counted pixels, what a real rig (no truth)
// can measure. Needs OpenGL (xvfb-run); "n/a" without.
// --blender: a Blender session (docs/blender.md) too, on scripts/blender_scenes.py's glossy_plastic (one Principled
// BSDF) at 160x120, 16 samples a pixel: no truth there, so only the held-out photographs (and no ggx fit: the
// scene's light is Blender's); skipped when blender is not on PATH. --blender-only: no simulated scene.
//
// The sessions' calib/ is the simulator's truth (write_true_calibration): this measures where the views are, not the
// calibration. The adaptive planner projects with the true intrinsics too (camera=...).
//
// Usage: bench_adaptive_sampling [work_dir] [--scenes patchwork,ggx4,lights2] [--schemes "adaptive:60;spiral:60:5@85"]
//        [--fits "phong:1,phong:1 sa,ggx:iso"] [--diagnose] [--no-noise] [--blender] [--blender-only]
// (default /tmp/vdrig_bench_adaptive, every scene and scheme, phong:1; prints one table per scene). --fits fits each
// session with each model (" sa": solid-angle weights, PhongFitOptions::solid_angle_weights; " sl": shared lights,
// MapFitOptions::shared_lights, the words in any order; ggx with the scene's one
// light, skipped on a scene lit otherwise). `vdrig fit` weights adaptive sessions by default (--weights auto), so its
// figures for an adaptive session are the " sa" rows, for a uniform one the plain rows; --diagnose adds per material
// where the error is (cone, grazing, else); --no-noise turns the simulated sensor's photon and read noise off (what is
// left of an error then is sampling and model, not noise).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
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

/// One fit of a captured session: the figures of the bench's table.
struct FitRow {
  std::string fit;  // what was fitted, e.g. "phong:1" or "phong:1 sa" (solid-angle weights)
  double mean_rel = 0;
  double mean_smooth_rel = 0;  // the same without brushed metal, whose bumps are finer than a texel (noisy: +-0.05)
  double worst_rel = 0;
  std::string worst_material;
  std::string diagnosis;      // --diagnose: per material, where the error is
  double compare_codes = -1;  // mean |render - photo| at the held-out photographs, 8-bit codes (-1: not measured)
};

struct Row {
  std::string scheme;
  int views = 0;
  double move_s = 0;
  double global_move_s = 0;  // the same views routed at once from home
  double shoot_s = 0;        // the bracket's exposures over every frame
  double plan_s = 0;         // the adaptive planner's wall time
  std::vector<FitRow> fits;
  double seconds = 0;
  std::string stopped;
};

/// How a session is fitted: the model, with or without solid-angle (Voronoi) weights.
struct FitVariant {
  std::string model = "phong:1";
  bool solid_angle = false;
  bool shared_lights = false;  // " sl": MapFitOptions::shared_lights (the lights estimated over the map, lobes refitted
                               // at their mirror directions where that wins by BIC)
  std::string label() const { return model + (solid_angle ? " sa" : "") + (shared_lights ? " sl" : ""); }
};

struct BenchOptions {
  std::vector<FitVariant> fits = {FitVariant{}};
  bool diagnose = false;
  bool truth = true;                           // the scene is the truth (not a Blender session)
  const capture::Session* held_out = nullptr;  // the held-out photographs, if captured
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

/// The mean |render - photo| of a fitted map at the held-out photographs (8-bit codes), -1 when it cannot be measured.
double compare_codes(const fitting::ParameterMap& map, const capture::Session& held_out, const fs::path& work) {
  const fs::path map_file = work / "map.exr";
  if (auto written = map.write(map_file); !written) return -1;
  pipeline::CompareOptions co;
  co.out_dir = work / "compare";
  std::vector<int> views;
  for (const auto& v : held_out.manifest().views) views.push_back(v.index);
  auto compared = pipeline::compare_maps(held_out, {map_file}, views, co);
  if (!compared) {
    std::fprintf(stderr, "compare: %s\n", compared.error().describe().c_str());
    return -1;
  }
  double sum = 0;
  long long n = 0;
  for (const auto& r : compared->rows) {
    sum += r.all.mean * static_cast<double>(r.all.samples);
    n += r.all.samples;
  }
  return n ? sum / static_cast<double>(n) : -1;
}

Result<FitRow> fit_and_evaluate(const fitting::ObservationMap& obs, const sim::Scene& scene, const FitVariant& variant,
                                const BenchOptions& bench, const fs::path& work) {
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
  fit.shared_lights = variant.shared_lights;
  auto map = fitting::fit_parameter_map(obs, fit);
  if (!map) return map.error();
  FitRow row;
  row.fit = variant.label();
  if (bench.held_out) row.compare_codes = compare_codes(map.value(), *bench.held_out, work);
  if (!bench.truth) return row;
  auto report = pipeline::evaluate_map(map.value(), scene, {});
  if (!report) return report.error();
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
  if (bench.diagnose) row.diagnosis = diagnose(map.value(), scene, report.value());
  return row;
}

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
                    const BenchOptions& bench) {
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
  for (const auto& variant : bench.fits) {
    // A BRDF model needs the scene's one point light: not on a scene lit otherwise (lights2), nor on a Blender session
    // (its light is the .blend's, not the stand-in scene's).
    if (variant.model.rfind("ggx", 0) == 0 && (!bench.truth || !pipeline::session_light_of(scene))) continue;
    auto fit = fit_and_evaluate(obs.value(), scene, variant, bench, dir.parent_path());
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

void print_header(bool truth) {
  std::printf(
      "| scheme | views | moves s | same views routed at once s | shooting s | planning s | rig time s | fit |%s"
      " held-out photos: mean abs. codes | bench s | stopped |\n",
      truth ? " mean rel. RMS | mean, no brushed metal | worst material (rel. RMS) |" : "");
  std::printf("|---|---|---|---|---|---|---|---|%s---|---|---|\n", truth ? "---|---|---|" : "");
}

void print_row(const Row& r, bool truth) {
  for (const auto& f : r.fits) {
    std::printf("| `%s` | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %s |", r.scheme.c_str(), r.views, r.move_s,
                r.global_move_s, r.shoot_s, r.plan_s, r.move_s + r.shoot_s + r.plan_s, f.fit.c_str());
    if (truth)
      std::printf(" %.4f | %.4f | %s (%.4f) |", f.mean_rel, f.mean_smooth_rel, f.worst_material.c_str(), f.worst_rel);
    if (f.compare_codes >= 0)
      std::printf(" %.2f |", f.compare_codes);
    else
      std::printf(" n/a |");
    std::printf(" %.0f | %s |\n", r.seconds, r.stopped.c_str());
    if (!f.diagnosis.empty()) std::printf("%s", f.diagnosis.c_str());
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  fs::path work = "/tmp/vdrig_bench_adaptive";
  std::vector<std::string> scene_names = {"patchwork", "ggx4", "lights2"};
  // ahead=1: each batch planned and routed alone (the loop before the joint route), for comparison.
  // ahead=1: each batch planned and routed alone (the loop before the joint route), for comparison.
  std::vector<std::string> schemes = {"adaptive:30",     "adaptive:45",     "adaptive:60",  "adaptive:60,ahead=1",
                                      "spiral:30:3@85",  "spiral:60:5@85",  "latlong:4:85", "icosahedron:2@85",
                                      "spiral:120:7@85", "icosahedron:3@85"};
  std::vector<std::string> blender_schemes = {"adaptive:60", "spiral:60:5@85", "icosahedron:3@85"};
  BenchOptions bench;
  bool blender = false, noise = true;
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
      blender_schemes = schemes;
    } else if (arg == "--fits" && has_value) {
      // e.g. "phong:1,phong:1 sa,ggx:iso": each session fitted so (" sa": solid-angle weights).
      bench.fits.clear();
      for (const auto& f : split_commas(argv[++i])) {
        // A model, then optional words: "sa" (solid-angle weights), "sl" (shared lights).
        FitVariant v;
        std::istringstream words(f);
        words >> v.model;
        for (std::string w; words >> w;) {
          if (w == "sa") {
            v.solid_angle = true;
          } else if (w == "sl") {
            v.shared_lights = true;
          } else {
            std::fprintf(stderr, "--fits: unknown word \"%s\" in \"%s\" (sa, sl)\n", w.c_str(), f.c_str());
            return 2;
          }
        }
        bench.fits.push_back(v);
      }
    } else if (arg == "--diagnose") {
      bench.diagnose = true;
    } else if (arg == "--no-noise") {
      noise = false;
    } else if (arg == "--blender") {
      blender = true;
    } else if (arg == "--blender-only") {
      blender = true;
      scene_names.clear();
    } else if (arg.rfind("--", 0) != 0) {
      work = arg;
    } else {
      std::fprintf(stderr,
                   "usage: bench_adaptive_sampling [work_dir] [--scenes a,b] [--schemes \"s1;s2\"] "
                   "[--fits \"phong:1,phong:1 sa,ggx:iso\"] [--diagnose] [--no-noise] [--blender] [--blender-only]\n");
      return 2;
    }
  }
  fs::create_directories(work);
  (void)log::set_level("warn");
  const CameraModel camera{200, 150, 300.0, 300.0, 99.5, 74.5, 0, 0, 0, 0, 0};
  const fs::path camera_yml = work / "camera.yml";
  if (!camera.save_yaml(camera_yml)) return 1;
  for (const auto& name : scene_names) {
    const std::string scene = name == "ggx4" ? write_ggx_scene(work).string() : name;
    json rc = rig_config(scene);
    if (!noise) rc["sim"]["camera"]["full_well_e"] = 0;  // photon and read noise off (docs/sim.md)
    auto scene_r = sim::make_scene(scene);
    if (!scene_r) return 1;
    auto held_out = held_out_session(work / "held_out", rc, scene_r.value());
    if (!held_out) std::fprintf(stderr, "held-out session: %s\n", held_out.error().describe().c_str());
    bench.truth = true;
    bench.held_out = held_out ? &held_out.value() : nullptr;
    std::printf("\nscene %s: at %dx%d texels, relative RMS vs the truth over 1000 directions\n", name.c_str(), kTexels,
                kTexels);
    print_header(true);
    for (const auto& scheme : schemes) {
      auto row = measure(work / "session", rc, scheme, camera_yml, bench);
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
    bench.truth = false;
    bench.held_out = held_out ? &held_out.value() : nullptr;
    std::printf("\nBlender session (Cycles, glossy_plastic.blend, 160x120, 16 samples): at %dx%d texels, no truth\n",
                kTexels, kTexels);
    print_header(false);
    for (const auto& scheme : blender_schemes) {
      auto row = measure(work / "session", rc, scheme, small_yml, bench);
      if (!row) {
        std::printf("| %s | failed: %s |\n", scheme.c_str(), row.error().describe().c_str());
        continue;
      }
      print_row(row.value(), false);
    }
  }
  return 0;
}

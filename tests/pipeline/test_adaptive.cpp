// Adaptive sampling (capture/adaptive.hpp, pipeline/adaptive_stage.hpp) on a small simulated scene with one narrow
// highlight: the batches go into the highlight's cone where a uniform scheme of the same size misses it; budgets are
// never exceeded; SIGKILL at random moments and resuming gives the same views as an uninterrupted run (noiseless, and
// with noise seeded by the shot: docs/sim.md); bad settings are refused naming the reason. The planner projects with
// the simulator's TRUE camera (written as camera.yml): the test is not about calibration.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <random>
#include <thread>

#include "vdrig/capture/adaptive.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/route.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/pipeline/adaptive_stage.hpp"
#include "vdrig/rig/lamp.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/kill_when_grown.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

/// The mirror direction of the scene's light about the normal, at the surface centre: the highlight's axis, 5 deg from
/// a view of the base scheme (icosahedron:1), so that the base sees the highlight's flank.
const Vec3d kHighlight = Vec3d(-0.5266, -0.3687, 0.766);  // azimuth 215 deg, zenith 40 deg

/// `ggx`: the same highlight from a GGX metal (roughness 0.1: alpha 0.01, a support cone of ~1.5 deg in view space;
/// Fresnel's rise at grazing view), instead of the Phong-form gloss.
fs::path write_scene(const fs::path& dir, bool ggx = false) {
  json scene = {
      {"format", "vdrig-scene"},
      {"version", 1},
      {"name", "narrow-highlight"},
      {"width_mm", 300.0},
      {"height_mm", 300.0},
      {"materials", {{{"name", "gloss"}, {"kd", {0.15, 0.15, 0.15}}, {"ks", {0.8, 0.8, 0.8}}, {"shininess", 300.0}}}},
      {"patches", {{{"x0_mm", -150.0}, {"y0_mm", -150.0}, {"x1_mm", 150.0}, {"y1_mm", 150.0}, {"material", 0}}}},
      {"markers", json::array()},
      {"lights", {{{"position_mm", {1579.8, 1106.1, 2298.1}}, {"intensity", {4.8e7, 4.8e7, 4.8e7}}}}}};
  if (ggx)
    scene["materials"] = {{{"name", "ggx metal"},
                           {"kind", "ggx"},
                           {"kd", {0.05, 0.05, 0.05}},
                           {"roughness", 0.1},
                           {"f0", {0.9, 0.9, 0.9}}}};
  const fs::path path = dir / "scene.json";
  std::ofstream(path) << scene.dump(2);
  return path;
}

struct AdaptiveRig {
  fs::path root;
  json rig_config;
  fs::path camera_yml;
};

/// `noise_seed` empty: a noiseless sensor; else strong noise (a 300 e- well, 8 e- read noise) seeded that way
/// (docs/sim.md). Strong, because the planner's picks survive the default 20000 e- well's noise: killed and resumed
/// under the default seeding, 0 of 35 views differed at seeds 1 and 2; with 300 e- and seed 2, 10 of 35.
AdaptiveRig make_setup(const std::string& name, const std::string& noise_seed = "", bool ggx = false) {
  AdaptiveRig s;
  s.root = test::fresh_temp_dir("adaptive_" + name);
  const fs::path scene = write_scene(s.root, ggx);
  json sensor = {{"width", 160}, {"height", 120}, {"fx", 800}, {"fy", 800},           {"cx", 79.5},
                 {"cy", 59.5},   {"k1", 0},       {"k2", 0},   {"response", "linear"}};
  if (noise_seed.empty())
    sensor.update({{"full_well_e", 0}, {"read_noise_e", 0}});
  else
    sensor.update({{"noise_seed", noise_seed}, {"full_well_e", 300}});
  s.rig_config =
      sim::sim_rig_config({{"scene", scene.string()}, {"seed", 2}, {"samples_per_axis", 1}, {"camera", sensor}});
  // The simulator's true intrinsics: this test is about planning, not calibration.
  CameraModel camera{160, 120, 800.0, 800.0, 79.5, 59.5, 0, 0, 0, 0, 0};
  s.camera_yml = s.root / "camera.yml";
  EXPECT_TRUE(camera.save_yaml(s.camera_yml));
  return s;
}

Result<rig::Rig> make_rig(const json& config) { return sim::simulator_and_hardware_backends().make_rig(config); }

fs::path create(const AdaptiveRig& s, const std::string& dir_name, const std::string& scheme) {
  const fs::path dir = s.root / dir_name;
  auto rig = make_rig(s.rig_config);
  EXPECT_TRUE(rig) << rig.error().describe();
  capture::PlanRequest req;
  req.rig_config = s.rig_config;
  req.scheme = scheme;
  req.bracket = "fixed:0.25,0.01";
  req.stage = rig->stage->spec();
  req.surface_width_mm = req.surface_height_mm = 300;
  auto manifest =
      capture::is_adaptive_scheme(scheme) ? capture::plan_adaptive_manifest(req) : capture::plan_manifest(req);
  EXPECT_TRUE(manifest) << manifest.error().describe();
  EXPECT_TRUE(capture::Session::create(dir, manifest.value()));
  return dir;
}

Status run(const fs::path& dir) {
  auto session = capture::Session::open_for_capture(dir);
  if (!session) return session.error();
  auto rig = make_rig(session->manifest().rig_config);
  if (!rig) return rig.error();
  auto planner = make_coarse_fit_planner();
  capture::AdaptiveOptions o;
  o.capture.bracket = capture::parse_bracket(session->manifest().bracket).value();
  o.capture.disk_reserve_bytes = 0;
  return capture::run_adaptive_session(rig.value(), session.value(), *planner, o);
}

int views_within(const capture::Session& session, double degrees, int from_view = 0) {
  int n = 0;
  for (const auto& v : session.manifest().views)
    if (v.index >= from_view && v.direction.dot(kHighlight.normalized()) >= std::cos(degrees * kPi / 180)) ++n;
  return n;
}

/// The stage's moves of a session, from home through every view in capture order (the route planner's move model).
double session_moves_s(const capture::Session& session, const rig::StageSpec& stage) {
  double moves_s = 0;
  PanTilt at{0, 0};
  for (const auto& v : session.manifest().views) {
    moves_s += capture::move_time_s(stage, at, v.target);
    at = v.target;
  }
  return moves_s;
}

/// A uniform scheme's moves, routed at once from home (plan_manifest's route).
double uniform_moves_s(const AdaptiveRig& s, const std::string& scheme, const rig::StageSpec& stage) {
  auto samples = capture::generate(scheme);
  EXPECT_TRUE(samples);
  auto geometry = capture::geometry_from_rig_config(s.rig_config);
  EXPECT_TRUE(geometry);
  const capture::TargetPlan targets = capture::plan_targets(geometry.value(), stage, samples->directions);
  std::vector<PanTilt> pts;
  for (const auto& t : targets.reachable) pts.push_back(t.pan_tilt);
  return capture::plan_route(stage, PanTilt{0, 0}, pts).planned_time_s;
}

std::string spec(const AdaptiveRig& s, const std::string& settings) {
  return "adaptive:" + settings + ",camera=" + s.camera_yml.string();
}

TEST(Adaptive, PutsItsBatchesIntoTheNarrowHighlightWhereAUniformSchemeMissesIt) {
  const auto t0 = std::chrono::steady_clock::now();
  const AdaptiveRig s = make_setup("highlight");
  const fs::path dir = create(s, "adaptive", spec(s, "40,base=icosahedron:1@85"));
  ASSERT_TRUE(run(dir));
  auto session = capture::Session::open(dir);
  ASSERT_TRUE(session);
  const int n = static_cast<int>(session->manifest().views.size());
  const int base = 17;
  EXPECT_LE(n, 40);
  EXPECT_GT(n, base);
  EXPECT_EQ(session->completed_view_count(), n);
  const auto progress = capture::adaptive_progress(session.value());
  ASSERT_TRUE(progress.stopped);
  // The narrow lobes' axes meet at the one light (the mirror probes' light estimate, docs/sampling.md).
  for (const auto& b : progress.batches) EXPECT_EQ(b.info.value("lights_estimated", 0), 1) << "batch " << b.batch;
  // The two-models term is on (docs/sampling.md) and, at its weight, leaves the highlight its views (below).
  double disagree = 0;
  for (const auto& b : progress.batches) disagree += b.info.value("disagree_value", 0.0);
  EXPECT_GT(disagree, 0.0);
  const int adaptive_in_cone = views_within(session.value(), 12.0, base);
  // The uniform schemes of the same size.
  int uniform_best = 0;
  for (const std::string& uniform :
       std::vector<std::string>{"spiral:" + std::to_string(n) + ":4@85", "stratified:5x8:1@85"}) {
    auto samples = capture::generate(uniform);
    ASSERT_TRUE(samples);
    int in = 0;
    for (const auto& d : samples->directions) in += d.dot(kHighlight.normalized()) >= std::cos(12.0 * kPi / 180);
    uniform_best = std::max(uniform_best, in);
  }
  std::printf(
      "%d views (%d adaptive, %d of them within 12 deg of the highlight; uniform schemes: at most %d), "
      "stopped: %s, %.1f s\n",
      n, n - base, adaptive_in_cone, uniform_best, progress.stopped->c_str(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  EXPECT_GT(2 * adaptive_in_cone, n - base) << "most adaptive views in the highlight's cone";
  // The joint route (ahead=3, the default): the stage's moves stay near those of a uniform scheme of the same size
  // routed at once, although the base is toured before any batch is known, and below those of batches planned and
  // routed alone (ahead=1). Measured: 57.4 s against spiral:40's 50.1 s (1.15x) and ahead=1's 63.5 s.
  const rig::StageSpec stage = make_rig(s.rig_config)->stage->spec();
  const double moves_s = session_moves_s(session.value(), stage);
  const double uniform_s = uniform_moves_s(s, "spiral:" + std::to_string(n) + ":4@85", stage);
  const fs::path alone_dir = create(s, "alone", spec(s, "40,base=icosahedron:1@85,ahead=1"));
  ASSERT_TRUE(run(alone_dir));
  const double alone_s = session_moves_s(capture::Session::open(alone_dir).value(), stage);
  std::printf("moves %.1f s; ahead=1: %.1f s; spiral:%d routed at once %.1f s\n", moves_s, alone_s, n, uniform_s);
  EXPECT_LE(moves_s, 1.3 * uniform_s);
  EXPECT_LT(moves_s, alone_s);
  EXPECT_LE(uniform_best, 3);
  EXPECT_GE(adaptive_in_cone, 3 * std::max(uniform_best, 1));
  fs::remove_all(s.root);
}

TEST(Adaptive, TheGgxPlannerPutsItsBatchesIntoAGgxHighlight) {
  // model=ggx fits ggx:iso per coarse texel under the lamp the simulator records in the rig config and turns it into
  // the planner's lobe (docs/sampling.md, "adaptive"); model=phong on the same GGX metal for comparison.
  const auto t0 = std::chrono::steady_clock::now();
  const AdaptiveRig s = make_setup("ggx", "", /*ggx=*/true);
  const int base = 17;
  auto in_cone = [&](const std::string& settings, int* views, double* predicted) {
    const fs::path dir = create(s, settings.find("ggx") != std::string::npos ? "ggx" : "phong", spec(s, settings));
    EXPECT_TRUE(run(dir));
    auto session = capture::Session::open(dir);
    EXPECT_TRUE(session);
    *views = static_cast<int>(session->manifest().views.size());
    const auto progress = capture::adaptive_progress(session.value());
    *predicted = progress.batches.empty() ? -1 : progress.batches.back().predicted_error;
    return views_within(session.value(), 12.0, base);
  };
  int n_ggx = 0, n_phong = 0;
  double e_ggx = 0, e_phong = 0;
  const int ggx = in_cone("40,base=icosahedron:1@85,model=ggx", &n_ggx, &e_ggx);
  const int phong = in_cone("40,base=icosahedron:1@85", &n_phong, &e_phong);
  std::printf(
      "model=ggx: %d of %d adaptive views within 12 deg of the highlight (predicted error %.4f); model=phong: %d of %d "
      "(%.4f); %.1f s\n",
      ggx, n_ggx - base, e_ggx, phong, n_phong - base, e_phong,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  EXPECT_GT(n_ggx, base);
  EXPECT_LE(n_ggx, 40);
  // Measured: 21 of 23 in the cone (model=phong 19 of 23); predicted error 0.060 against the Phong fit's 0.113.
  EXPECT_GT(2 * ggx, n_ggx - base) << "most adaptive views in the highlight's cone";
  EXPECT_GE(ggx, 14);
  // The predicted error is the GGX fit's held-out prediction, which fits the GGX metal better than Phong lobes.
  EXPECT_GT(e_ggx, 0);
  EXPECT_LT(e_ggx, 0.8 * e_phong);
  fs::remove_all(s.root);
}

TEST(Adaptive, TheGgxPlannerNeedsTheLamp) {
  // Refused before the session is made, naming what to give; the simulator's rig config records its scene's lamp.
  const AdaptiveRig s = make_setup("ggx_lamp", "", /*ggx=*/true);
  auto planner = make_coarse_fit_planner();
  auto settings = capture::parse_adaptive_scheme(spec(s, "40,model=ggx"));
  ASSERT_TRUE(settings) << settings.error().describe();
  EXPECT_TRUE(planner->check(settings.value(), s.root / "new", s.rig_config));
  json no_lamp = s.rig_config;
  no_lamp["light"] = rig::without_lamp_keys(no_lamp["light"]);
  const Status refused = planner->check(settings.value(), s.root / "new", no_lamp);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("position_mm"), std::string::npos) << refused.error().message;
  json no_light = s.rig_config;
  no_light.erase("light");
  EXPECT_FALSE(planner->check(settings.value(), s.root / "new", no_light));
  // model=phong needs no lamp.
  settings->model = "phong";
  EXPECT_TRUE(planner->check(settings.value(), s.root / "new", no_light));
  fs::remove_all(s.root);
}

TEST(Adaptive, BudgetsAreNeverExceeded) {
  const AdaptiveRig s = make_setup("budget");
  {
    // A base whose moves alone pass the time budget is refused when planned (27.7 s of moves for this base).
    auto rig = make_rig(s.rig_config);
    capture::PlanRequest req;
    req.rig_config = s.rig_config;
    req.scheme = spec(s, "30,base=icosahedron:1@85,time_s=20");
    req.bracket = "fixed:0.25";
    req.stage = rig->stage->spec();
    auto refused = capture::plan_adaptive_manifest(req);
    ASSERT_FALSE(refused);
    EXPECT_NE(refused.error().message.find("more than time_s = 20"), std::string::npos) << refused.error().message;
  }
  for (const double time_s : {0.0, 30.0, 33.0}) {
    const std::string settings = "30,base=icosahedron:1@85,batch=4" +
                                 (time_s > 0 ? ",time_s=" + std::to_string(time_s) : std::string()) + ",gain=0";
    const fs::path dir = create(s, "budget_" + std::to_string(static_cast<int>(time_s)), spec(s, settings));
    ASSERT_TRUE(run(dir));
    auto session = capture::Session::open(dir);
    ASSERT_TRUE(session);
    auto rig = make_rig(s.rig_config);
    // The stage's moves, recomputed from the plan: from home through every view in order.
    double moves_s = 0;
    PanTilt at{0, 0};
    for (const auto& v : session->manifest().views) {
      moves_s += capture::move_time_s(rig->stage->spec(), at, v.target);
      at = v.target;
    }
    const auto progress = capture::adaptive_progress(session.value());
    ASSERT_TRUE(progress.stopped);
    std::printf("time_s %.0f: %zu views, %.1f s of moves; %s\n", time_s, session->manifest().views.size(), moves_s,
                progress.stopped->c_str());
    EXPECT_LE(session->manifest().views.size(), 30u);
    if (time_s > 0) {
      EXPECT_LE(moves_s, time_s + 1e-6);
      EXPECT_NE(progress.stopped->find("time budget"), std::string::npos) << *progress.stopped;
    } else {
      EXPECT_EQ(session->manifest().views.size(), 30u);  // gain=0: never converged, the view budget stops it
    }
  }
  fs::remove_all(s.root);
}

std::vector<Vec3d> view_directions(const fs::path& dir) {
  std::vector<Vec3d> d;
  auto session = capture::Session::open(dir);
  if (!session) return d;
  const capture::Manifest& m = session->manifest();
  for (const auto& v : m.views) d.push_back(v.direction);
  return d;
}

/// Kills the session's capture at random moments (seeded) until it stops, resumes it, and compares its views with an
/// uninterrupted run's: the same directions (1e-12) in the same order, each complete once in the journal. Returns the
/// number of views that differ (0 expected).
int killed_and_resumed_differ(const AdaptiveRig& s, int* kills) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string scheme = spec(s, "35,base=icosahedron:1@85,batch=5,gain=0");
  const fs::path reference = create(s, "reference", scheme);
  EXPECT_TRUE(run(reference));
  const std::vector<Vec3d> expected = view_directions(reference);
  EXPECT_EQ(expected.size(), 35u);

  const fs::path dir = create(s, "killed", scheme);
  const fs::path journal = capture::SessionLayout(dir).journal_file();
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uintmax_t> grow(1, 4000);
  std::uniform_int_distribution<int> extra_us(0, 20000);
  *kills = 0;
  for (int round = 0; round < 40; ++round) {
    const std::uintmax_t target = fs::file_size(journal) + grow(rng);
    const auto status = vdrig::test::kill_when_grown([&] { return run(dir); }, journal, target,
                                                     [&] { return extra_us(rng); }, std::chrono::seconds(20));
    EXPECT_TRUE(status) << "fork failed";
    if (!status) return -1;
    if (WIFSIGNALED(*status)) {
      ++*kills;
    } else {
      EXPECT_EQ(WEXITSTATUS(*status), 0);
      auto after = capture::Session::open(dir);
      EXPECT_TRUE(after);
      if (!after || capture::adaptive_progress(after.value()).stopped) break;
    }
  }
  EXPECT_TRUE(run(dir));
  const std::vector<Vec3d> got = view_directions(dir);
  EXPECT_EQ(got.size(), expected.size());
  int differ = 0;
  for (size_t i = 0; i < std::min(got.size(), expected.size()); ++i)
    if (!((got[i] - expected[i]).norm() < 1e-12)) ++differ;
  // Each view complete exactly once in the journal.
  std::vector<int> completions(got.size(), 0);
  std::ifstream in(journal);
  std::string line;
  while (std::getline(in, line)) {
    const json j = json::parse(line, nullptr, false);
    EXPECT_FALSE(j.is_discarded());
    if (!j.is_discarded() && j.value("type", "") == "view_complete") ++completions.at(j.at("view").get<size_t>());
  }
  for (size_t v = 0; v < got.size(); ++v) EXPECT_EQ(completions[v], 1) << "view " << v;
  std::printf("%d kills, %d of %zu views differ, %.1f s\n", *kills, differ, expected.size(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return differ;
}

/// Killed at least 5 times and resumed, the session ends with the uninterrupted run's views, each complete once.
void expect_kills_and_resumes_change_nothing(const AdaptiveRig& s) {
  int kills = 0;
  EXPECT_EQ(killed_and_resumed_differ(s, &kills), 0);
  EXPECT_GE(kills, 5);
  fs::remove_all(s.root);
}

TEST(Adaptive, SigkillAndResumeGiveTheSameViewsNoneDoubled) {
  expect_kills_and_resumes_change_nothing(make_setup("kill"));
}

// With sensor noise on, later batches are planned from noisy images: a resumed process must shoot the same noise,
// which the simulator's "noise_seed": "shot" gives (seeded by what is shot, not by the process's frame counter).
TEST(Adaptive, WithNoiseSeededByTheShotSigkillAndResumeGiveTheSameViews) {
  expect_kills_and_resumes_change_nothing(make_setup("kill_noise", "shot"));
}

// The contrast (run with --gtest_also_run_disabled_tests; docs/sim.md): noise seeded by the frame counter, the default,
// gives a resumed process other noise, and the views diverge.
TEST(Adaptive, DISABLED_WithNoiseSeededByTheFrameCounterResumedViewsDiverge) {
  const AdaptiveRig s = make_setup("kill_noise_sequence", "sequence");
  int kills = 0;
  EXPECT_GT(killed_and_resumed_differ(s, &kills), 0);
  fs::remove_all(s.root);
}

TEST(Adaptive, BadSettingsAreRefusedWithTheReason) {
  auto why = [](const std::string& spec) {
    auto r = capture::parse_adaptive_scheme(spec);
    EXPECT_FALSE(r) << spec;
    return r ? std::string() : r.error().message;
  };
  EXPECT_NE(why("adaptive:10,base=icosahedron:2").find("73 directions, not fewer than N = 10"), std::string::npos);
  const std::string two = why("adaptive:60,batch=0,colour=red");
  EXPECT_NE(two.find("unknown key \"colour\""), std::string::npos) << two;
  EXPECT_NE(two.find("batch must be in 1..100"), std::string::npos) << two;
  EXPECT_NE(why("adaptive:x").find("N must be a whole number"), std::string::npos);
  EXPECT_NE(why("adaptive:60,time_s=-1").find("time_s"), std::string::npos);
  EXPECT_NE(why("adaptive:60,base=adaptive:20").find("not adaptive"), std::string::npos);
  EXPECT_NE(why("adaptive:60,res=1").find("res"), std::string::npos);
  EXPECT_NE(why("adaptive:60,ahead=0").find("ahead"), std::string::npos);
  EXPECT_NE(why("adaptive:60,model=blinn").find("model must be phong or ggx"), std::string::npos);
  EXPECT_NE(why("adaptive:60,model=").find("model must be phong or ggx"), std::string::npos);
  auto ggx = capture::parse_adaptive_scheme("adaptive:60,model=ggx");
  ASSERT_TRUE(ggx) << ggx.error().describe();
  EXPECT_EQ(ggx->model, "ggx");
  EXPECT_EQ(ggx->to_spec(), "adaptive:60,model=ggx");
  EXPECT_EQ(ggx->to_json()["model"], "ggx");
  EXPECT_EQ(capture::parse_adaptive_scheme("adaptive:60,model=phong")->to_spec(), "adaptive:60");
  // The coarse map's side follows the model unless given: 16 for ggx, 12 for phong (docs/sampling.md).
  EXPECT_EQ(ggx->res, 16);
  EXPECT_EQ(capture::parse_adaptive_scheme("adaptive:60")->res, 12);
  auto ggx12 = capture::parse_adaptive_scheme("adaptive:60,model=ggx,res=12");
  ASSERT_TRUE(ggx12);
  EXPECT_EQ(ggx12->res, 12);
  EXPECT_EQ(ggx12->to_spec(), "adaptive:60,res=12,model=ggx");
  EXPECT_EQ(capture::parse_adaptive_scheme(ggx12->to_spec())->res, 12);
  auto ok = capture::parse_adaptive_scheme("adaptive:60,batch=8,time_s=120");
  ASSERT_TRUE(ok) << ok.error().describe();
  EXPECT_EQ(ok->batch, 8);
  EXPECT_EQ(capture::parse_adaptive_scheme(ok->to_spec())->to_spec(), ok->to_spec());
}

TEST(Adaptive, TheDefaultBaseIsHalfOfNUniform) {
  // docs/results.md, "Adaptive sampling": with 17 base views the planner left the grazing directions of the matte
  // materials to chance; half of N in a spiral fits them as well as a uniform scheme does.
  auto base_of = [](const std::string& spec) {
    auto a = capture::parse_adaptive_scheme(spec);
    EXPECT_TRUE(a) << spec;
    return a ? a->base_scheme() : std::string();
  };
  // To the candidates' zenith limit (75 by default: the observation map's footprint limit, docs/sampling.md).
  EXPECT_EQ(base_of("adaptive:60"), "spiral:30:3@75");
  EXPECT_EQ(base_of("adaptive:30"), "spiral:15:2@75");
  EXPECT_EQ(base_of("adaptive:3"), "spiral:1:1@75");
  EXPECT_EQ(base_of("adaptive:60,zenith=82.5"), "spiral:30:3@82.5");
  EXPECT_EQ(base_of("adaptive:60,base=icosahedron:1@85"), "icosahedron:1@85");
  auto a = capture::parse_adaptive_scheme("adaptive:60");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->to_spec(), "adaptive:60");
  EXPECT_EQ(a->to_json()["base"], "spiral:30:3@75");
  auto base = capture::generate(a->base_scheme());
  ASSERT_TRUE(base);
  EXPECT_EQ(base->directions.size(), 30u);
}

}  // namespace
}  // namespace vdrig::pipeline

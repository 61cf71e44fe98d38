// The simulated rig behind the device interfaces: config keys, move timing, homing, limits, read-back, the surface
// offset, injected faults, and that its frames are the renderer's.
#include <gtest/gtest.h>

#include "vdrig/rig/motion.hpp"

#include <chrono>
#include <cstdio>
#include <fstream>

#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/instant_stage.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::sim {
namespace {

using nlohmann::json;

json small_sim(json extra = json::object()) {
  json j = {{"camera", {{"width", 64}, {"height", 48}, {"fx", 40.0}, {"fy", 40.0}}}, {"samples_per_axis", 1}};
  j.update(extra);
  return j;
}

rig::Rig make(const json& sim_section) {
  rig::BackendRegistry registry;
  register_backends(registry);
  auto r = registry.make_rig(sim_rig_config(sim_section));
  EXPECT_TRUE(r) << r.error().describe();
  return std::move(r.value());
}

double seconds_of(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

TEST(SimConfig, ReadsKeysAndRejectsUnknownOnes) {
  auto c = SimConfig::from_json({{"surface_offset_mm", {3, -4, 5}},
                                 {"distance_mm", 2000},
                                 {"faults", {{"drop_frame_at", {2, 5}}, {"slow_write_ms", 1.5}}},
                                 {"stage", {{"tilt_max_deg", 80}}}});
  ASSERT_TRUE(c) << c.error().describe();
  EXPECT_EQ(c->geometry.surface_offset_mm, Vec3d(3, -4, 5));
  EXPECT_EQ(c->geometry.camera_distance_mm, 2000);
  EXPECT_EQ(c->faults.drop_frame_at, (std::vector<uint64_t>{2, 5}));
  EXPECT_EQ(c->faults.slow_write_ms, 1.5);
  EXPECT_NEAR(c->stage.tilt.max_rad, deg_to_rad(80), 1e-12);
  for (const json& bad :
       {json{{"scenery", "x"}}, json{{"faults", {{"drop_at", {1}}}}}, json{{"surface_offset_mm", {1, 2}}},
        json{{"faults", {{"drive_error_at", {0}}}}}, json{{"camera", {{"bits", 20}}}}}) {
    auto r = SimConfig::from_json(bad);
    EXPECT_FALSE(r) << bad.dump();
    if (!r) {
      EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
    }
  }
}

TEST(SimStage, TrapezoidTimes) {
  // The stage's move model (rig/motion.hpp), in degree units here: 30 deg/s, 60 deg/s^2.
  rig::AxisSpec axis;
  axis.max_speed_rad_s = 30;
  axis.accel_rad_s2 = 60;
  const auto trapezoid_time_s = [&](double d, double, double) { return rig::axis_move_time_s(d, axis); };
  // 90 deg at 30 deg/s, 60 deg/s^2: 0.5 s ramps over 7.5 deg each, 75 deg cruising at 30 deg/s -> 3.5 s.
  EXPECT_NEAR(trapezoid_time_s(90, 30, 60), 3.5, 1e-12);
  // 10 deg never reaches full speed: triangular, 2 sqrt(10 / 60).
  EXPECT_NEAR(trapezoid_time_s(10, 30, 60), 2 * std::sqrt(10.0 / 60.0), 1e-12);
  EXPECT_NEAR(trapezoid_time_s(-10, 30, 60), trapezoid_time_s(10, 30, 60), 1e-12);
  EXPECT_EQ(trapezoid_time_s(0, 30, 60), 0.0);
}

TEST(SimStage, MovesTakeScaledTrapezoidTimeAndReadBack) {
  rig::Rig r = make(small_sim({{"time_scale", 0.04}}));
  const PanTilt target{deg_to_rad(90), deg_to_rad(10)};  // pan dominates: 3.5 s * 0.04 = 0.14 s
  Status st;
  const double t = seconds_of([&] { st = r.stage->move_to(target); });
  ASSERT_TRUE(st) << st.describe();
  EXPECT_GE(t, 0.14);
  EXPECT_LT(t, 0.6);
  auto pos = r.stage->position();
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->pan_rad, target.pan_rad);
  EXPECT_EQ(pos->tilt_rad, target.tilt_rad);
  // Homing drives back to zero (the same 3.5 s scaled).
  const double th = seconds_of([&] { st = r.stage->home(); });
  ASSERT_TRUE(st);
  EXPECT_GE(th, 0.14);
  EXPECT_EQ(r.stage->position()->pan_rad, 0.0);
  EXPECT_EQ(r.stage->position()->tilt_rad, 0.0);
}

// `vdrig rig check --self-test` on the simulator: moves that take time_scale x their profile time are what the
// simulator promises, not a drive that ignored its speeds. Unscaled, a 5 deg move (0.58 s of profile) taking 0.03 s
// (time_scale 0.05) or none (0) failed as "much faster than the configured profile".
TEST(SimStage, SelfTestPassesAtTheConfiguredTimeScale) {
  for (const double time_scale : {0.0, 0.05}) {
    rig::Rig r = make(small_sim({{"time_scale", time_scale}}));
    EXPECT_EQ(r.stage->wall_time_scale(), time_scale);
    const auto steps = rig::run_self_test(r);
    ASSERT_FALSE(steps.empty());
    for (const auto& step : steps)
      EXPECT_TRUE(step.passed) << "time_scale " << time_scale << ", " << step.name << ": " << step.detail;
  }
}

// With "state_file" the simulated stage keeps its position between rigs built from the config (between `vdrig rig
// move` and `vdrig rig position`), as a real drive does; without it every rig starts at 0, 0.
TEST(SimStage, KeepsItsPositionInTheStateFileAcrossRigs) {
  const vdrig::test::TempDir dir("sim_state");
  const std::string state = (dir.path() / "stage.json").string();
  const PanTilt target{deg_to_rad(10), deg_to_rad(20)};
  {
    rig::Rig first = make(small_sim({{"state_file", state}}));
    EXPECT_EQ(first.stage->position()->pan_rad, 0.0) << "no state file yet: the stage starts at 0, 0";
    ASSERT_TRUE(first.stage->move_to(target));
  }
  {
    rig::Rig second = make(small_sim({{"state_file", state}}));
    EXPECT_NEAR(second.stage->position()->pan_rad, target.pan_rad, 1e-12);
    EXPECT_NEAR(second.stage->position()->tilt_rad, target.tilt_rad, 1e-12);
    ASSERT_TRUE(second.stage->home());
  }
  {
    rig::Rig third = make(small_sim({{"state_file", state}}));
    EXPECT_EQ(third.stage->position()->pan_rad, 0.0);
    EXPECT_EQ(third.stage->position()->tilt_rad, 0.0);
    ASSERT_TRUE(third.stage->move_to(target));
  }
  rig::Rig without = make(small_sim());
  EXPECT_EQ(without.stage->position()->pan_rad, 0.0) << "no state_file: nothing is kept";

  // A damaged state file is an error naming it, not a stage silently at 0, 0.
  { std::ofstream(state, std::ios::trunc) << "{\"pan_deg\": "; }
  rig::BackendRegistry registry;
  register_backends(registry);
  auto refused = registry.make_rig(sim_rig_config(small_sim({{"state_file", state}})));
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find(state), std::string::npos) << refused.error().message;
}

TEST(SimStage, TargetsOutsideTheLimitsAreErrorsNotClamps) {
  rig::Rig r = make(small_sim());
  const PanTilt ok{deg_to_rad(20), deg_to_rad(30)};
  ASSERT_TRUE(r.stage->move_to(ok));
  for (const PanTilt bad : {PanTilt{0, deg_to_rad(86)}, PanTilt{0, deg_to_rad(-6)}, PanTilt{deg_to_rad(361), 0},
                            PanTilt{std::nan(""), 0}}) {
    const Status st = r.stage->move_to(bad);
    ASSERT_FALSE(st);
    EXPECT_EQ(st.error().code, ErrorCode::kInvalidArgument);
    EXPECT_EQ(r.stage->position()->tilt_rad, ok.tilt_rad);  // did not move at all
    EXPECT_EQ(r.stage->position()->pan_rad, ok.pan_rad);
  }
}

TEST(SimCamera, FramesAreTheRenderedSceneAtTheStagePoseWithTheSurfaceOffset) {
  const json section = small_sim(
      {{"surface_offset_mm", {40, -25, 10}},
       {"camera", {{"width", 64}, {"height", 48}, {"fx", 40.0}, {"fy", 40.0}, {"response", "linear"}, {"bits", 12}}}});
  rig::Rig r = make(section);
  const PanTilt pt{deg_to_rad(30), deg_to_rad(45)};
  ASSERT_TRUE(r.stage->move_to(pt));
  ASSERT_TRUE(r.camera->set_exposure(0.8, 1.0));
  auto frame = r.camera->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(frame->measured.tilt_rad, pt.tilt_rad);
  const SimConfig c = SimConfig::from_json(section).value();
  const ViewPose pose = rig::surface_pose(c.geometry, pt);
  const cv::Mat expected =
      expose(render_radiance(make_scene("patchwork").value(), c.camera, pose, 1), 0.8, 1.0, c.sensor, frame->sequence);
  EXPECT_EQ(cv::norm(frame->image, expected, cv::NORM_INF), 0.0);
  // The offset matters: without it the image differs.
  const cv::Mat centred =
      expose(render_radiance(make_scene("patchwork").value(), c.camera, rig::surface_pose({}, pt), 1), 0.8, 1.0,
             c.sensor, frame->sequence);
  EXPECT_GT(cv::norm(frame->image, centred, cv::NORM_INF), 100.0);
}

TEST(SimConfig, ImperfectRigKeys) {
  auto c = SimConfig::from_json({{"pan_zero_deg", 0.3}, {"tilt_zero_deg", -0.2}, {"pan_axis_tilt_deg", {0.5, -0.1}}});
  ASSERT_TRUE(c) << c.error().describe();
  EXPECT_NEAR(c->geometry.pan_zero_rad, deg_to_rad(0.3), 1e-15);
  EXPECT_NEAR(c->geometry.tilt_zero_rad, deg_to_rad(-0.2), 1e-15);
  EXPECT_NEAR(c->geometry.pan_axis_tilt_x_rad, deg_to_rad(0.5), 1e-15);
  EXPECT_NEAR(c->geometry.pan_axis_tilt_y_rad, deg_to_rad(-0.1), 1e-15);
  for (const json& bad : {json{{"pan_axis_tilt_deg", {20, 0}}}, json{{"pan_axis_tilt_deg", {1}}},
                          json{{"pan_zero_deg", 400}}, json{{"tilt_zero_deg", "0.3"}}}) {
    auto r = SimConfig::from_json(bad);
    EXPECT_FALSE(r) << bad.dump();
  }
}

TEST(SimCamera, AnImperfectRigReportsReadingsAndShowsTheTrueAngles) {
  // Encoder zeros: the stage reads back what it was told (the encoder), the platform stands at reading - zero.
  const json section = small_sim(
      {{"pan_zero_deg", 4.0},
       {"tilt_zero_deg", -3.0},
       {"camera", {{"width", 64}, {"height", 48}, {"fx", 40.0}, {"fy", 40.0}, {"response", "linear"}, {"bits", 12}}}});
  rig::Rig r = make(section);
  const PanTilt pt{deg_to_rad(30), deg_to_rad(45)};
  ASSERT_TRUE(r.stage->move_to(pt));
  ASSERT_TRUE(r.camera->set_exposure(0.8, 1.0));
  auto frame = r.camera->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(frame->measured.pan_rad, pt.pan_rad);
  EXPECT_EQ(frame->measured.tilt_rad, pt.tilt_rad);
  const SimConfig c = SimConfig::from_json(section).value();
  const auto render = [&](const PanTilt& at) {
    return expose(render_radiance(make_scene("patchwork").value(), c.camera, rig::surface_pose({}, at), 1), 0.8, 1.0,
                  c.sensor, frame->sequence);
  };
  const PanTilt true_angles{pt.pan_rad - deg_to_rad(4.0), pt.tilt_rad + deg_to_rad(3.0)};
  EXPECT_LE(cv::norm(frame->image, render(true_angles), cv::NORM_INF), 1.0);
  EXPECT_GT(cv::norm(frame->image, render(pt), cv::NORM_INF), 100.0);
}

TEST(SimCamera, PairedWithAnotherStageItRendersThePoseThatStageReports) {
  rig::BackendRegistry registry;
  register_backends(registry);
  // A stage of another backend: stands wherever it is told, instantly.
  registry.add_stage(
      "other",
      [](const json&, rig::RigContext&) -> Result<std::unique_ptr<rig::PanTiltStage>> {
        return std::unique_ptr<rig::PanTiltStage>(std::make_unique<test::InstantStage>("other", SimConfig().stage));
      },
      {.check = [](const json& section) -> Result<json> { return section; }});
  const json section = small_sim(
      {{"camera", {{"width", 64}, {"height", 48}, {"fx", 40.0}, {"fy", 40.0}, {"response", "linear"}, {"bits", 12}}}});
  auto r = registry.make_rig({{"stage", {{"backend", "other"}}}, {"camera", {{"backend", "sim"}}}, {"sim", section}});
  ASSERT_TRUE(r) << r.error().describe();
  const PanTilt pt{deg_to_rad(30), deg_to_rad(45)};
  ASSERT_TRUE(r->stage->move_to(pt));
  ASSERT_TRUE(r->camera->set_exposure(0.8, 1.0));
  auto frame = r->camera->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(frame->measured.pan_rad, pt.pan_rad);
  EXPECT_EQ(frame->measured.tilt_rad, pt.tilt_rad);
  const SimConfig c = SimConfig::from_json(section).value();
  const cv::Mat expected =
      expose(render_radiance(make_scene("patchwork").value(), c.camera, rig::surface_pose(c.geometry, pt), 1), 0.8, 1.0,
             c.sensor, frame->sequence);
  EXPECT_EQ(cv::norm(frame->image, expected, cv::NORM_INF), 0.0);
}

TEST(SimFaults, MoveTimeoutStopsHalfWayAndDriveErrorDoesNotMove) {
  rig::Rig r = make(small_sim({{"faults", {{"move_timeout_at", {2}}, {"drive_error_at", {3}}}}}));
  ASSERT_TRUE(r.stage->home());  // not counted
  const PanTilt a{deg_to_rad(40), deg_to_rad(20)};
  ASSERT_TRUE(r.stage->move_to(a));                                // move 1
  Status st = r.stage->move_to({deg_to_rad(80), deg_to_rad(60)});  // move 2: times out half way
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().code, ErrorCode::kTimeout);
  EXPECT_NEAR(r.stage->position()->pan_rad, deg_to_rad(60), 1e-12);
  EXPECT_NEAR(r.stage->position()->tilt_rad, deg_to_rad(40), 1e-12);
  st = r.stage->move_to(a);  // move 3: drive alarm, stays put
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().code, ErrorCode::kDevice);
  EXPECT_NEAR(r.stage->position()->pan_rad, deg_to_rad(60), 1e-12);
  ASSERT_TRUE(r.stage->move_to(a));  // move 4: fine again
  EXPECT_EQ(r.stage->position()->pan_rad, a.pan_rad);
}

TEST(SimFaults, DroppedFrameTimesOutAndLeavesASequenceGap) {
  rig::Rig r = make(small_sim({{"faults", {{"drop_frame_at", {2}}}}}));
  auto f1 = r.camera->capture();
  ASSERT_TRUE(f1);
  auto f2 = r.camera->capture();
  ASSERT_FALSE(f2);
  EXPECT_EQ(f2.error().code, ErrorCode::kTimeout);
  auto f3 = r.camera->capture();
  ASSERT_TRUE(f3);
  EXPECT_EQ(f3->sequence, f1->sequence + 2);
}

TEST(SimFaults, CameraDisconnectsForGivenCallsOrForGood) {
  {
    rig::Rig r = make(small_sim({{"faults", {{"disconnect_camera_at", {2}}, {"disconnect_calls", 3}}}}));
    ASSERT_TRUE(r.camera->capture());
    auto f = r.camera->capture();  // call 2: gone (1st refused call)
    ASSERT_FALSE(f);
    EXPECT_EQ(f.error().code, ErrorCode::kDisconnected);
    const Status st = r.camera->set_exposure(0.01, 1.0);  // 2nd refused call
    ASSERT_FALSE(st);
    EXPECT_EQ(st.error().code, ErrorCode::kDisconnected);
    auto info = r.camera->info();  // 3rd
    ASSERT_FALSE(info);
    EXPECT_EQ(info.error().code, ErrorCode::kDisconnected);
    EXPECT_TRUE(r.camera->capture());  // back
  }
  {
    rig::Rig r = make(small_sim({{"faults", {{"disconnect_camera_at", {1}}}}}));
    for (int i = 0; i < 5; ++i) {
      auto f = r.camera->capture();
      ASSERT_FALSE(f);
      EXPECT_EQ(f.error().code, ErrorCode::kDisconnected);
    }
  }
}

TEST(SimFaults, SlowWritesAndDeterminism) {
  rig::Rig r = make(small_sim({{"faults", {{"slow_write_ms", 40}}}}));
  Status st;
  EXPECT_GE(seconds_of([&] { st = r.stage->move_to({0.1, 0.1}); }), 0.04);
  ASSERT_TRUE(st);
  EXPECT_GE(seconds_of([&] { st = r.camera->set_exposure(0.01, 1.0); }), 0.04);
  // Two rigs of one config (noise on) take identical photographs.
  const json noisy = small_sim(
      {{"seed", 9},
       {"camera",
        {{"width", 64}, {"height", 48}, {"fx", 40.0}, {"fy", 40.0}, {"full_well_e", 3000}, {"read_noise_e", 2}}}});
  rig::Rig a = make(noisy), b = make(noisy);
  for (rig::Rig* x : {&a, &b}) ASSERT_TRUE(x->stage->move_to({0.3, 0.5}));
  auto fa = a.camera->capture(), fb = b.camera->capture();
  ASSERT_TRUE(fa && fb);
  EXPECT_EQ(cv::norm(fa->image, fb->image, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(fa->image, a.camera->capture()->image, cv::NORM_INF), 0.0);  // next frame: new noise
}

TEST(SimCamera, NoiseSeededByTheShotRepeatsAcrossRigsAndDiffersBetweenPoses) {
  const auto noisy = [](const std::string& noise_seed) {
    return small_sim({{"seed", 9},
                      {"camera",
                       {{"width", 64},
                        {"height", 48},
                        {"fx", 40.0},
                        {"fy", 40.0},
                        {"full_well_e", 3000},
                        {"read_noise_e", 2},
                        {"noise_seed", noise_seed}}}});
  };
  const PanTilt p{0.3, 0.5}, q{0.3 + 1e-9, 0.5};  // q: a pose that renders alike, shot by its own noise
  const auto shoot = [](rig::Rig& r, const PanTilt& at, double exposure_s) {
    EXPECT_TRUE(r.stage->move_to(at));
    EXPECT_TRUE(r.camera->set_exposure(exposure_s, 1.0));
    auto f = r.camera->capture();
    EXPECT_TRUE(f) << f.error().describe();
    return f ? f.value() : Frame{};
  };
  // Rig a shoots p first; rig b (a resumed process) shoots other frames before: p is still bit-identical.
  rig::Rig a = make(noisy("shot")), b = make(noisy("shot"));
  const Frame a_p = shoot(a, p, 0.01);
  shoot(b, q, 0.01);
  shoot(b, p, 0.005);
  const Frame b_p = shoot(b, p, 0.01);
  EXPECT_NE(a_p.sequence, b_p.sequence);  // the frame counter still counts (a gap still shows)
  EXPECT_EQ(cv::norm(a_p.image, b_p.image, cv::NORM_INF), 0.0);
  // Another pose, rendered alike (q is 1e-9 rad from p): the codes differ by other noise, in most pixels.
  const auto differing = [](const cv::Mat& x, const cv::Mat& y) {
    cv::Mat ne;
    cv::compare(x.reshape(1), y.reshape(1), ne, cv::CMP_NE);
    return cv::countNonZero(ne) / static_cast<double>(ne.total());
  };
  const double other_pose = differing(a_p.image, shoot(a, q, 0.8).image);
  EXPECT_GT(other_pose, 0.5);
  // Under the default seeding the same shot after another frame has other noise (what a resumed capture met).
  rig::Rig c = make(noisy("sequence")), d = make(noisy("sequence"));
  shoot(d, q, 0.8);
  const double resumed = differing(shoot(c, p, 0.8).image, shoot(d, p, 0.8).image);
  EXPECT_GT(resumed, 0.5);
  std::printf("codes differing: another pose %.3f, default seeding after another frame %.3f\n", other_pose, resumed);
  EXPECT_FALSE(SimConfig::from_json({{"camera", {{"noise_seed", "random"}}}}));
}

TEST(SimConfig, CameraSizeIsLimited) {
  // Issue #18: a 100000 x 100000 simulated camera ended in bad_alloc after the session folder was made.
  auto huge = SimConfig::from_json({{"camera", {{"width", 100000}, {"height", 100000}}}});
  ASSERT_FALSE(huge);
  EXPECT_EQ(huge.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(huge.error().message.find(std::to_string(SimConfig::kMaxCameraSide)), std::string::npos)
      << huge.error().message;
  SimConfig c;
  c.camera.width = SimConfig::kMaxCameraSide + 1;
  std::string why;
  EXPECT_FALSE(c.is_valid(&why));
  EXPECT_TRUE(SimConfig::from_json({{"camera", {{"width", 320}, {"height", 240}}}}));
}

}  // namespace
}  // namespace vdrig::sim

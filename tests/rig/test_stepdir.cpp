// gpio-stepdir: the trapezoidal step planner against the analytic profile, the stage's motion and homing logic on a
// simulated axis, and (only with a real /dev/gpiochip*) opening the chip through libgpiod.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include "step_profile.hpp"
#include "stepdir_stage.hpp"
#ifdef VDRIG_HAVE_GPIOD
#include "gpiod_lines.hpp"
#endif

namespace vdrig::rig {
namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;

TEST(TrapezoidProfile, TrapezoidHasTheRightStepsTimeAndShape) {
  // 1000 steps at 500 steps/s, 1000 steps/s^2: 125 steps to accelerate, T = N/v + v/a = 2.5 s.
  const TrapezoidProfile p(1000, 500.0, 1000.0);
  const auto t = p.step_times();
  ASSERT_EQ(t.size(), 1000u);
  EXPECT_NEAR(p.total_s(), 2.5, 1e-12);
  EXPECT_NEAR(t.back(), 2.5, 1e-12);
  EXPECT_NEAR(p.peak_speed_steps_s(), 500.0, 1e-12);
  EXPECT_NEAR(p.accel_s(), 0.5, 1e-12);
  EXPECT_NEAR(t[0], std::sqrt(2.0 / 1000.0), 1e-12);  // x = a t^2 / 2 reaches 1
  for (size_t k = 1; k < t.size(); ++k) ASSERT_GT(t[k], t[k - 1]) << k;
  // Accelerating: intervals shrink; cruising: 1/v; decelerating: mirror image of the acceleration.
  for (size_t k = 1; k < 124; ++k) EXPECT_LT(t[k + 1] - t[k], t[k] - t[k - 1]) << k;
  for (size_t k = 130; k < 870; ++k) EXPECT_NEAR(t[k + 1] - t[k], 1.0 / 500.0, 1e-9) << k;
  for (size_t k = 1; k < 120; ++k) EXPECT_NEAR(t[k] - t[k - 1], t[999 - k] - t[998 - k], 1e-9) << k;
  // Speed from step spacing in the middle of the acceleration: v = a t.
  const double v_mid = 1.0 / (t[50] - t[49]);
  EXPECT_NEAR(v_mid, 1000.0 * 0.5 * (t[50] + t[49]), 2.0);
  // Position function agrees with the step times.
  for (int k : {1, 60, 125, 500, 900, 1000}) EXPECT_NEAR(p.position_at(p.step_time_s(k)), k, 1e-9) << k;
}

TEST(TrapezoidProfile, ShortMoveIsATriangle) {
  // 100 steps cannot reach 500 steps/s at 1000 steps/s^2 (needs 250): peak sqrt(N a) = 316.2, T = 2 sqrt(N/a).
  const TrapezoidProfile p(100, 500.0, 1000.0);
  const auto t = p.step_times();
  ASSERT_EQ(t.size(), 100u);
  EXPECT_NEAR(p.peak_speed_steps_s(), std::sqrt(100.0 * 1000.0), 1e-9);
  EXPECT_NEAR(p.total_s(), 2.0 * std::sqrt(0.1), 1e-12);
  EXPECT_NEAR(t[49], std::sqrt(2.0 * 50 / 1000.0), 1e-12);  // half way at the apex
  EXPECT_EQ(TrapezoidProfile(0, 1.0, 1.0).total_s(), 0.0);
  EXPECT_EQ(TrapezoidProfile(1, 1.0, 2.0).step_times().size(), 1u);
}

/// A stepper axis in memory: physical step position and a switch closed at or beyond `switch_at`.
struct SimAxis final : StepDirAxisIo {
  std::atomic<int64_t>* pos;
  int64_t switch_at;
  bool switch_negative;
  bool enabled = false, positive = true;
  int pulses = 0;
  SimAxis(std::atomic<int64_t>* p, int64_t sw, bool neg) : pos(p), switch_at(sw), switch_negative(neg) {}
  Status set_enable(bool on) override {
    enabled = on;
    return Status::ok();
  }
  Status set_direction(bool pos_dir) override {
    positive = pos_dir;
    return Status::ok();
  }
  Status pulse() override {
    if (!enabled) return make_error(ErrorCode::kDevice, "step while disabled");
    *pos += positive ? 1 : -1;
    ++pulses;
    return Status::ok();
  }
  Result<bool> limit_active() override { return switch_negative ? *pos <= switch_at : *pos >= switch_at; }
};

nlohmann::json stepdir_config() {
  const nlohmann::json axis = {{"step_line", 0},         {"dir_line", 1},        {"limit_line", 2},
                               {"steps_per_degree", 10}, {"min_deg", -10},       {"max_deg", 180},
                               {"max_speed_deg_s", 200}, {"accel_deg_s2", 2000}, {"home_speed_deg_s", 100}};
  nlohmann::json tilt = axis;
  tilt["step_line"] = 3;
  tilt["dir_line"] = 4;
  tilt["limit_line"] = 5;
  tilt["home_direction"] = "positive";
  tilt["min_deg"] = -90;
  tilt["max_deg"] = 10;
  return {{"backend", "gpio-stepdir"}, {"pan", axis}, {"tilt", tilt}};
}

struct SimStage {
  std::atomic<int64_t> pan_pos{0}, tilt_pos{0};
  SimAxis* pan;
  SimAxis* tilt;
  std::unique_ptr<StepDirStage> stage;
  SimStage(int64_t pan_switch, int64_t tilt_switch, const nlohmann::json& config = stepdir_config()) {
    auto c = StepDirStageConfig::parse(config);
    EXPECT_TRUE(c) << c.error().describe();
    auto p = std::make_unique<SimAxis>(&pan_pos, pan_switch, true);
    auto t = std::make_unique<SimAxis>(&tilt_pos, tilt_switch, false);
    pan = p.get();
    tilt = t.get();
    stage = std::make_unique<StepDirStage>(c.value(), std::move(p), std::move(t));
  }
};

TEST(StepDirStage, HomesOntoTheSwitchsOpeningEdgeAndMovesOnATrapezoid) {
  SimStage s(-300, 150);  // pan switch 30 deg below the start, tilt switch 15 deg above
  EXPECT_EQ(s.stage->move_to({0.1, 0.0}).error().code, ErrorCode::kDevice);  // not homed
  ASSERT_TRUE(s.stage->home());
  // Zero is the first step off the switch: physical -299 (pan, switch at <= -300) and 149 (tilt, >= 150).
  EXPECT_EQ(s.pan_pos.load(), -299);
  EXPECT_EQ(s.tilt_pos.load(), 149);
  EXPECT_EQ(s.stage->steps(true), 0);

  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(s.stage->move_to({90.0 * kDeg, -45.0 * kDeg}));
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Pan: 900 steps at 2000 steps/s, 20000 steps/s^2: T = 900/2000 + 2000/20000 = 0.55 s (tilt is shorter).
  EXPECT_GE(took, 0.55);
  EXPECT_LT(took, 0.9);
  EXPECT_EQ(s.pan_pos.load(), -299 + 900);
  EXPECT_EQ(s.tilt_pos.load(), 149 - 450);
  auto p = s.stage->position();
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->pan_rad / kDeg, 90.0, 1e-9);
  EXPECT_NEAR(p->tilt_rad / kDeg, -45.0, 1e-9);
  EXPECT_EQ(s.stage->move_to({200.0 * kDeg, 0.0}).error().code, ErrorCode::kInvalidArgument);
}

struct FakeEstop final : StepDirInput {
  std::atomic<bool>* pressed;
  explicit FakeEstop(std::atomic<bool>* p) : pressed(p) {}
  Result<bool> active() override { return pressed->load(); }
};

TEST(StepDirStage, EmergencyStopHaltsAtOnceAndNeedsARehome) {
  nlohmann::json config = stepdir_config();
  config["estop_line"] = 6;
  auto c = StepDirStageConfig::parse(config);
  ASSERT_TRUE(c) << c.error().describe();
  std::atomic<int64_t> pan_pos{0}, tilt_pos{0};
  std::atomic<bool> pressed{false};
  StepDirStage stage(c.value(), std::make_unique<SimAxis>(&pan_pos, -300, true),
                     std::make_unique<SimAxis>(&tilt_pos, 150, false), std::make_unique<FakeEstop>(&pressed));
  ASSERT_TRUE(stage.home());
  const int64_t pan_home = pan_pos.load();
  Status moved;
  std::thread mover([&] { moved = stage.move_to({90.0 * kDeg, 0.0}); });  // 0.55 s
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  pressed = true;
  const auto t0 = std::chrono::steady_clock::now();
  mover.join();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.05);
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kDevice);
  EXPECT_NE(moved.error().message.find("emergency stop"), std::string::npos) << moved.describe();
  const int64_t halted_at = pan_pos.load();
  EXPECT_GT(halted_at, pan_home);
  EXPECT_LT(halted_at, pan_home + 900);  // halted on the way
  // Latched: no move until home(), and no home while the button is pressed.
  pressed = false;
  EXPECT_EQ(stage.move_to({0.0, 0.0}).error().code, ErrorCode::kDevice);
  EXPECT_EQ(pan_pos.load(), halted_at);
  pressed = true;
  EXPECT_EQ(stage.home().error().code, ErrorCode::kDevice);
  EXPECT_EQ(pan_pos.load(), halted_at);
  pressed = false;
  ASSERT_TRUE(stage.home());
  EXPECT_TRUE(stage.move_to({10.0 * kDeg, 0.0}));
  // The emergency stop shares no line with an axis.
  config["estop_line"] = 2;
  EXPECT_FALSE(StepDirStageConfig::parse(config));
}

TEST(StepDirStage, SwitchNotFoundAndSwitchHitAreDeviceErrors) {
  {
    nlohmann::json c = stepdir_config();
    c["pan"]["home_max_travel_deg"] = 40;
    SimStage s(-100000, 150, c);  // pan switch beyond home_max_travel (40 deg = 400 steps)
    const Status st = s.stage->home();
    ASSERT_FALSE(st);
    EXPECT_EQ(st.error().code, ErrorCode::kDevice);
    EXPECT_NE(st.error().message.find("pan limit switch not found"), std::string::npos) << st.describe();
    EXPECT_EQ(s.pan_pos.load(), -400);
  }
  SimStage s(-300, 150);
  ASSERT_TRUE(s.stage->home());
  s.pan->switch_at = -299 - 50;  // the switch moved (or steps were lost): 5 deg below zero now
  const Status st = s.stage->move_to({-10.0 * kDeg, 0.0});
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().code, ErrorCode::kDevice);
  EXPECT_NE(st.error().message.find("limit switch closed"), std::string::npos) << st.describe();
  EXPECT_EQ(s.stage->steps(true), -50);  // stopped at the switch
}

TEST(StepDirStage, StopCancelsAMove) {
  SimStage s(-300, 150);
  ASSERT_TRUE(s.stage->home());
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    (void)s.stage->stop();
  });
  const Status st = s.stage->move_to({180.0 * kDeg, 0.0});  // 0.95 s
  stopper.join();
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().code, ErrorCode::kCancelled);
  EXPECT_GT(s.stage->steps(true), 0);
  EXPECT_LT(s.stage->steps(true), 1800);
}

TEST(StepDirStage, BadConfigIsRejected) {
  auto c = stepdir_config();
  c["pan"].erase("steps_per_degree");
  c["tilt"]["dir_line"] = 3;    // same as its step line
  c["tilt"]["limit_line"] = 0;  // pan's step line
  c["pan"]["max_speed_deg_s"] = 5000;
  auto r = StepDirStageConfig::parse(c);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message.find("pan: \"steps_per_degree\" is required"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("tilt: line 3 is used twice"), std::string::npos) << r.error().message;
  c = stepdir_config();
  c["tilt"]["limit_line"] = 0;
  r = StepDirStageConfig::parse(c);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("line 0 is used by both pan and tilt"), std::string::npos) << r.error().message;
  c = stepdir_config();
  c["pan"]["max_speed_deg_s"] = 5000;  // 50000 steps/s
  r = StepDirStageConfig::parse(c);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("20000 steps/s"), std::string::npos) << r.error().message;
}

TEST(GpioChip, OpensARealChip) {
#ifndef VDRIG_HAVE_GPIOD
  GTEST_SKIP() << "built without libgpiod (VDRIG_WITH_GPIOD=OFF)";
#else
  std::string found;
  if (std::filesystem::exists("/dev"))
    for (const auto& e : std::filesystem::directory_iterator("/dev"))
      if (e.path().filename().string().rfind("gpiochip", 0) == 0) found = e.path().filename().string();
  if (found.empty()) GTEST_SKIP() << "no /dev/gpiochip* on this machine";
  auto chip = GpioChip::open(found);
  ASSERT_TRUE(chip) << chip.error().describe();
  EXPECT_GT((*chip)->num_lines(), 0);
  // A line past the end is refused with the chip's size, not requested.
  auto line = GpioLine::input(*chip, (*chip)->num_lines(), "vdrig-test", false, false);
  ASSERT_FALSE(line);
  EXPECT_EQ(line.error().code, ErrorCode::kInvalidArgument);
#endif
}

}  // namespace
}  // namespace vdrig::rig

#include "stepdir_stage.hpp"

#include <time.h>

#include <cmath>
#include <optional>

#include "axis_settings.hpp"
#include "step_profile.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::rig {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegPerRad = 180.0 / kPi;

StepDirAxisConfig parse_axis(Settings& parent, const nlohmann::json& section, const std::string& where) {
  Settings s(section, where, {"backend"});  // accepted in axis sections as before
  StepDirAxisConfig a;
  a.step_line = static_cast<int>(s.required_integer("step_line", 0, 4095));
  a.dir_line = static_cast<int>(s.required_integer("dir_line", 0, 4095));
  a.limit_line = static_cast<int>(s.required_integer("limit_line", 0, 4095));
  a.enable_line = static_cast<int>(s.integer("enable_line", -1, -1, 4095));
  a.enable_active_low = s.boolean("enable_active_low", true);
  a.limit_active_low = s.boolean("limit_active_low", true);
  a.dir_invert = s.boolean("dir_invert", false);
  a.steps_per_rad = s.required_number("steps_per_degree", 1e-3, 1e7) * kDegPerRad;
  a.axis = read_axis_spec(s);
  a.home_positive = s.string("home_direction", "negative", {"negative", "positive"}) == "positive";
  a.home_speed_rad_s = s.number("home_speed_deg_s", 5.0, 1e-3, 1e4) / kDegPerRad;
  a.home_max_travel_rad = s.number("home_max_travel_deg", 400.0, 1e-3, 1e5) / kDegPerRad;
  a.home_backoff_rad = s.number("home_backoff_deg", 5.0, 1e-3, 360.0) / kDegPerRad;
  // Above ~20 kHz a sleeping user-space loop cannot keep the timing.
  if (a.axis.max_speed_rad_s * a.steps_per_rad > 20000.0)
    s.fail("max_speed_deg_s x steps_per_degree exceeds 20000 steps/s, beyond what user-space step timing can do");
  const int lines[] = {a.step_line, a.dir_line, a.limit_line, a.enable_line};
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      if (lines[i] >= 0 && lines[i] == lines[j]) s.fail("line " + std::to_string(lines[i]) + " is used twice");
  s.reject_unknown({"step_line", "dir_line", "limit_line", "enable_line", "enable_active_low", "limit_active_low",
                    "dir_invert", "steps_per_degree", "min_deg", "max_deg", "max_speed_deg_s", "accel_deg_s2",
                    "continuous", "home_direction", "home_speed_deg_s", "home_max_travel_deg", "home_backoff_deg"});
  parent.absorb(s);
  return a;
}

void sleep_until(const timespec& start, double offset_s) {
  timespec t = start;
  const double whole = std::floor(offset_s);
  t.tv_sec += static_cast<time_t>(whole);
  t.tv_nsec += static_cast<long>((offset_s - whole) * 1e9);
  if (t.tv_nsec >= 1000000000L) {
    t.tv_nsec -= 1000000000L;
    ++t.tv_sec;
  }
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) == EINTR) {
  }
}

}  // namespace

Result<StepDirStageConfig> StepDirStageConfig::parse(const nlohmann::json& settings) {
  Settings s(settings, "stage gpio-stepdir", {"backend"});
  StepDirStageConfig c;
  c.chip = s.string("chip", "gpiochip0");
  c.step_pulse_s = s.number("step_pulse_s", 5e-6, 1e-7, 1e-3);
  c.estop_line = static_cast<int>(s.integer("estop_line", -1, -1, 4095));
  c.estop_active_low = s.boolean("estop_active_low", true);
  c.pan = parse_axis(s, s.object("pan", true), "pan");
  c.tilt = parse_axis(s, s.object("tilt", true), "tilt");
  s.reject_unknown({"chip", "step_pulse_s", "estop_line", "estop_active_low", "pan", "tilt"});
  if (!s.is_valid(nullptr)) return s.error();
  // Both axes share one chip: no line may serve two purposes.
  for (int a : {c.pan.step_line, c.pan.dir_line, c.pan.limit_line, c.pan.enable_line})
    for (int b : {c.tilt.step_line, c.tilt.dir_line, c.tilt.limit_line, c.tilt.enable_line})
      if (a >= 0 && a == b) s.fail("line " + std::to_string(a) + " is used by both pan and tilt");
  for (const auto* ax : {&c.pan, &c.tilt})
    for (int a : {ax->step_line, ax->dir_line, ax->limit_line, ax->enable_line})
      if (c.estop_line >= 0 && a == c.estop_line)
        s.fail("line " + std::to_string(a) + " is both an axis line and the emergency stop");
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

nlohmann::json StepDirStageConfig::effective() const {
  nlohmann::json j = {{"backend", "gpio-stepdir"},
                      {"chip", chip},
                      {"step_pulse_s", step_pulse_s},
                      {"estop_line", estop_line},
                      {"estop_active_low", estop_active_low}};
  for (const auto& [key, a] : {std::pair{"pan", &pan}, std::pair{"tilt", &tilt}}) {
    nlohmann::json axis = axis_spec_json(a->axis);
    axis["step_line"] = a->step_line;
    axis["dir_line"] = a->dir_line;
    axis["limit_line"] = a->limit_line;
    axis["enable_line"] = a->enable_line;
    axis["enable_active_low"] = a->enable_active_low;
    axis["limit_active_low"] = a->limit_active_low;
    axis["dir_invert"] = a->dir_invert;
    axis["steps_per_degree"] = a->steps_per_rad / kDegPerRad;
    axis["home_direction"] = a->home_positive ? "positive" : "negative";
    axis["home_speed_deg_s"] = a->home_speed_rad_s * kDegPerRad;
    axis["home_max_travel_deg"] = a->home_max_travel_rad * kDegPerRad;
    axis["home_backoff_deg"] = a->home_backoff_rad * kDegPerRad;
    j[key] = axis;
  }
  return j;
}

StepDirStage::StepDirStage(StepDirStageConfig config, std::unique_ptr<StepDirAxisIo> pan_io,
                           std::unique_ptr<StepDirAxisIo> tilt_io, std::unique_ptr<StepDirInput> estop)
    : config_(std::move(config)), estop_(std::move(estop)) {
  VDRIG_CHECK(pan_io && tilt_io, "both axes need their lines");
  io_[0] = std::move(pan_io);
  io_[1] = std::move(tilt_io);
}

// The drivers stay enabled: dropping the holding torque would let the tilt axis sag under its load.
StepDirStage::~StepDirStage() = default;

Status StepDirStage::run(const Move (&moves)[2], bool (&hit_limit)[2]) {
  std::optional<TrapezoidProfile> profile[2];
  int64_t next[2] = {1, 1}, count[2] = {0, 0};
  int dir[2] = {0, 0};
  bool check_limit[2] = {false, false};
  for (int i = 0; i < 2; ++i) {
    hit_limit[i] = false;
    if (moves[i].steps == 0) continue;
    dir[i] = moves[i].steps > 0 ? 1 : -1;
    count[i] = std::abs(moves[i].steps);
    profile[i].emplace(count[i], moves[i].speed_steps_s, moves[i].accel_steps_s2);
    VDRIG_TRY(io_[i]->set_enable(true));
    VDRIG_TRY(io_[i]->set_direction(dir[i] > 0));
    // Only a move towards the switch can run onto it; checking costs one line read per step.
    check_limit[i] = (dir[i] > 0) == axis(i).home_positive;
  }
  timespec start;
  clock_gettime(CLOCK_MONOTONIC, &start);
  // Drivers want DIR stable some microseconds before the first STEP edge (DRV8825: 650 ns, TB6600: 5 us).
  const double setup_s = 20e-6;
  for (;;) {
    int i = -1;
    double t = 0.0;
    for (int a = 0; a < 2; ++a) {
      if (next[a] > count[a]) continue;
      const double ta = profile[a]->step_time_s(next[a]);
      if (i < 0 || ta < t) i = a, t = ta;
    }
    if (i < 0) return Status::ok();
    sleep_until(start, setup_s + t);
    VDRIG_TRY(check_estop());
    if (stop_requested_) {
      log::get("rig")->warn("gpio-stepdir: stopped during a move; steps may be lost at speed, home() advised");
      return make_error(ErrorCode::kCancelled, "gpio-stepdir: move stopped on request");
    }
    if (check_limit[i]) {
      auto limit = io_[i]->limit_active();
      if (!limit) return limit.error();
      if (*limit) {
        if (moves[i].stop_on_limit) {
          hit_limit[i] = true;
          count[i] = next[i] - 1;  // this axis is done
          continue;
        }
        return make_error(ErrorCode::kDevice, std::string("gpio-stepdir: ") + (i == 0 ? "pan" : "tilt") +
                                                  " limit switch closed during a move (lost steps or bad limits?)");
      }
    }
    VDRIG_TRY(io_[i]->pulse());
    pos_[i] += dir[i];
    ++next[i];
  }
}

Status StepDirStage::check_estop() {
  if (!estop_) return Status::ok();
  auto pressed = estop_->active();
  if (!pressed) return pressed.error();
  if (!*pressed) return Status::ok();
  if (!estop_fault_) log::get("rig")->error("gpio-stepdir: emergency stop pressed; motion halted, home() required");
  estop_fault_ = true;
  homed_ = false;
  return make_error(ErrorCode::kDevice,
                    "gpio-stepdir: emergency stop pressed; motion halted; release it and home() before moving again");
}

Status StepDirStage::home_axis(int i) {
  const StepDirAxisConfig& a = axis(i);
  const char* name = i == 0 ? "pan" : "tilt";
  const double speed = a.home_speed_rad_s * a.steps_per_rad;
  auto limit = io_[i]->limit_active();
  if (!limit) return limit.error();
  if (!*limit) {
    Move moves[2];
    moves[i] = {static_cast<int64_t>(std::ceil(a.home_max_travel_rad * a.steps_per_rad)) * (a.home_positive ? 1 : -1),
                speed, a.axis.accel_rad_s2 * a.steps_per_rad, true};
    moves[1 - i] = {};
    moves[1 - i].speed_steps_s = moves[1 - i].accel_steps_s2 = 1.0;
    bool hit[2];
    VDRIG_TRY(run(moves, hit));
    if (!hit[i])
      return make_error(ErrorCode::kDevice, std::string("gpio-stepdir: ") + name + " limit switch not found within " +
                                                std::to_string(a.home_max_travel_rad * kDegPerRad) + " deg");
  }
  // Creep back until the switch opens: its opening edge is more repeatable than the closing one at speed.
  VDRIG_TRY(io_[i]->set_direction(!a.home_positive));
  const double interval_s = 4.0 / speed;
  const int64_t max_steps = static_cast<int64_t>(std::ceil(a.home_backoff_rad * a.steps_per_rad));
  timespec start;
  clock_gettime(CLOCK_MONOTONIC, &start);
  for (int64_t k = 0;; ++k) {
    auto closed = io_[i]->limit_active();
    if (!closed) return closed.error();
    if (!*closed) break;
    if (k >= max_steps)
      return make_error(ErrorCode::kDevice, std::string("gpio-stepdir: ") + name + " limit switch still closed after " +
                                                std::to_string(a.home_backoff_rad * kDegPerRad) + " deg back-off");
    if (stop_requested_) return make_error(ErrorCode::kCancelled, "gpio-stepdir: homing stopped on request");
    sleep_until(start, 20e-6 + (k + 1) * interval_s);
    VDRIG_TRY(check_estop());
    VDRIG_TRY(io_[i]->pulse());
  }
  pos_[i] = 0;
  return Status::ok();
}

Status StepDirStage::home() {
  stop_requested_ = false;
  homed_ = false;
  VDRIG_TRY(check_estop());  // still pressed: nothing moves
  estop_fault_ = false;
  VDRIG_TRY(home_axis(1));  // tilt first: levels the platform before the pan axis turns
  VDRIG_TRY(home_axis(0));
  homed_ = true;
  return Status::ok();
}

Status StepDirStage::move_to(const PanTilt& target) {
  if (estop_fault_)
    return make_error(ErrorCode::kDevice, "gpio-stepdir: halted by the emergency stop; home() before moving again");
  if (!homed_) return make_error(ErrorCode::kDevice, "gpio-stepdir: not homed; call home() first");
  VDRIG_TRY(check_estop());
  const double t[2] = {target.pan_rad, target.tilt_rad};
  Move moves[2];
  for (int i = 0; i < 2; ++i) {
    const StepDirAxisConfig& a = axis(i);
    if (!std::isfinite(t[i])) return make_error(ErrorCode::kInvalidArgument, "gpio-stepdir: non-finite target");
    int64_t goal;
    if (a.axis.continuous) {
      const double current = static_cast<double>(pos_[i]) / a.steps_per_rad;
      goal = pos_[i] + std::llround(std::remainder(t[i] - current, 2.0 * kPi) * a.steps_per_rad);
    } else {
      if (t[i] < a.axis.min_rad - 1e-9 || t[i] > a.axis.max_rad + 1e-9)
        return make_error(ErrorCode::kInvalidArgument, std::string("gpio-stepdir: ") + (i == 0 ? "pan" : "tilt") +
                                                           " target " + std::to_string(t[i] * kDegPerRad) +
                                                           " deg outside [" +
                                                           std::to_string(a.axis.min_rad * kDegPerRad) + ", " +
                                                           std::to_string(a.axis.max_rad * kDegPerRad) + "] deg");
      goal = std::llround(t[i] * a.steps_per_rad);
    }
    moves[i] = {goal - pos_[i], a.axis.max_speed_rad_s * a.steps_per_rad, a.axis.accel_rad_s2 * a.steps_per_rad, false};
  }
  stop_requested_ = false;
  bool hit[2];
  return run(moves, hit);
}

Result<PanTilt> StepDirStage::position() {
  return PanTilt{static_cast<double>(pos_[0]) / config_.pan.steps_per_rad,
                 static_cast<double>(pos_[1]) / config_.tilt.steps_per_rad};
}

Status StepDirStage::stop() {
  stop_requested_ = true;
  return Status::ok();
}

}  // namespace vdrig::rig

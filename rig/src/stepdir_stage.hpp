// gpio-stepdir pan/tilt stage: two stepper drivers commanded by step/dir(/enable) lines, a limit switch per axis for
// homing, position = step count. The motion logic here talks to an abstract StepDirAxisIo, so it is tested with a
// simulated axis; gpio_stepdir_io.cpp supplies the libgpiod lines.
//
// Settings (JSON "stage" section; degrees and seconds):
//   "chip": "gpiochip0", "step_pulse_s": 5e-6,
//   "estop_line" (-1 = none: the emergency-stop input), "estop_active_low" (true: pressed reads low, a button to
//     ground with the pull-up),
//   "pan" / "tilt": { "step_line", "dir_line", "limit_line" (line offsets, required), "enable_line" (-1 = none),
//     "enable_active_low" (true), "limit_active_low" (true: switch to ground with pull-up), "dir_invert" (false),
//     "steps_per_degree" (required, > 0; motor steps x microsteps x gear ratio / 360),
//     "min_deg", "max_deg", "max_speed_deg_s", "accel_deg_s2", "continuous",
//     "home_direction" ("negative"|"positive"), "home_speed_deg_s" (5), "home_max_travel_deg" (400),
//     "home_backoff_deg" (5: how far to creep back off the switch at most) }
// Timing: steps are timed with absolute clock_nanosleep on CLOCK_MONOTONIC; on a non-realtime kernel expect tens of
// microseconds of jitter, fine for a few kHz step rate with a driver that microsteps.
// stop() halts at once (no deceleration: a step/dir driver stops as fast as we stop pulsing); after a stop at
// speed, steps may have been lost and home() is advised (logged).
#pragma once

#include <atomic>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

/// The emergency-stop input (logical: true while pressed).
class StepDirInput {
 public:
  virtual ~StepDirInput() = default;
  virtual Result<bool> active() = 0;
};

/// The lines of one axis. Values are logical: set_direction(true) = towards positive angles.
class StepDirAxisIo {
 public:
  virtual ~StepDirAxisIo() = default;
  virtual Status set_enable(bool on) = 0;
  virtual Status set_direction(bool positive) = 0;
  /// One step pulse (active for the configured pulse width, then inactive).
  virtual Status pulse() = 0;
  virtual Result<bool> limit_active() = 0;
};

struct StepDirAxisConfig {
  int step_line = -1, dir_line = -1, limit_line = -1, enable_line = -1;
  bool enable_active_low = true, limit_active_low = true, dir_invert = false;
  double steps_per_rad = 0.0;
  AxisSpec axis;
  bool home_positive = false;
  double home_speed_rad_s = 0.0;
  double home_max_travel_rad = 0.0;
  double home_backoff_rad = 0.0;
};

struct StepDirStageConfig {
  std::string chip = "gpiochip0";
  double step_pulse_s = 5e-6;
  int estop_line = -1;
  bool estop_active_low = true;
  StepDirAxisConfig pan, tilt;
  static Result<StepDirStageConfig> parse(const nlohmann::json& settings);
  /// The settings as the backend uses them, defaults filled in, in the section's JSON keys (`vdrig rig check`).
  nlohmann::json effective() const;
};

class StepDirStage final : public PanTiltStage {
 public:
  /// `estop` (may be null: no emergency stop) is read before every step: while it is active nothing moves.
  StepDirStage(StepDirStageConfig config, std::unique_ptr<StepDirAxisIo> pan_io, std::unique_ptr<StepDirAxisIo> tilt_io,
               std::unique_ptr<StepDirInput> estop = nullptr);
  ~StepDirStage() override;

  std::string backend() const override { return "gpio-stepdir"; }
  StageSpec spec() const override { return {config_.pan.axis, config_.tilt.axis}; }
  /// Homes tilt, then pan: each moves towards its switch at home speed until it closes (kDevice when it does not
  /// within home_max_travel), creeps back until it opens, and that step becomes 0. Clears an emergency-stop fault
  /// once the button is released (kDevice while it is still pressed).
  Status home() override;
  /// kDevice "not homed" before home(); kInvalidArgument outside the limits; kDevice when a limit switch closes
  /// on the way; kCancelled after stop(). The emergency stop pressed halts both axes at the next step and is kDevice;
  /// the stage then refuses every move (kDevice) until home(): steps were lost at speed.
  Status move_to(const PanTilt& target) override;
  Result<PanTilt> position() override;
  Status stop() override;

  int64_t steps(bool pan) const { return pan ? pos_[0].load() : pos_[1].load(); }

 private:
  struct Move {
    int64_t steps = 0;  // signed
    double speed_steps_s = 0.0;
    double accel_steps_s2 = 0.0;
    bool stop_on_limit = false;  // homing: end the move when the switch closes (not an error)
  };
  const StepDirAxisConfig& axis(int i) const { return i == 0 ? config_.pan : config_.tilt; }
  /// Runs both moves at once, each on its own trapezoid. `hit_limit[i]` tells whether axis i stopped on its switch.
  Status run(const Move (&moves)[2], bool (&hit_limit)[2]);
  Status home_axis(int i);
  /// kDevice when the emergency stop is pressed (latching the fault: homed_ false).
  Status check_estop();

  StepDirStageConfig config_;
  std::unique_ptr<StepDirAxisIo> io_[2];
  std::atomic<int64_t> pos_[2] = {0, 0};
  std::unique_ptr<StepDirInput> estop_;
  std::atomic<bool> stop_requested_{false};
  bool homed_ = false;
  bool estop_fault_ = false;  // latched by the emergency stop until home()
};

}  // namespace vdrig::rig

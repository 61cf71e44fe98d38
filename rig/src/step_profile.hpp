// Trapezoidal step timing for a stepper axis driven by step/dir pulses (gpio-stepdir backend), kept free of any
// chip I/O so it is tested on its own.
//
// A move of N steps accelerates at `accel` up to `max_speed`, cruises, and decelerates symmetrically; when N is too
// short to reach max_speed the profile is a triangle. Step k (1..N) is issued when the ideal position x(t) reaches k,
// so the first step comes at sqrt(2/accel) and the last exactly at total_s(): the pulse train follows the
// continuous profile to within one step.
#pragma once

#include <cstdint>
#include <vector>

namespace vdrig::rig {

class TrapezoidProfile {
 public:
  /// `steps` >= 0; max_speed (steps/s) and accel (steps/s^2) > 0 (VDRIG_CHECK).
  TrapezoidProfile(int64_t steps, double max_speed_steps_s, double accel_steps_s2);

  int64_t steps() const { return steps_; }
  /// Total duration of the move, s (0 for no steps).
  double total_s() const { return total_s_; }
  /// Highest speed reached: max_speed, or less on a triangle profile.
  double peak_speed_steps_s() const { return peak_speed_; }
  /// Duration of the acceleration phase (= of the deceleration phase), s.
  double accel_s() const { return accel_s_; }
  /// Time of step k (1..steps) from the start of the move, s.
  double step_time_s(int64_t k) const;
  /// Ideal position (steps) at time t (clamped to [0, total_s]).
  double position_at(double t_s) const;
  /// All step times (for tests and short moves; the stage walks step_time_s() instead of allocating).
  std::vector<double> step_times() const;

 private:
  int64_t steps_;
  double accel_;
  double peak_speed_ = 0.0;
  double accel_steps_ = 0.0;  // distance covered while accelerating
  double accel_s_ = 0.0;
  double total_s_ = 0.0;
};

}  // namespace vdrig::rig

#include "step_profile.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/core/result.hpp"

namespace vdrig::rig {

TrapezoidProfile::TrapezoidProfile(int64_t steps, double max_speed_steps_s, double accel_steps_s2)
    : steps_(steps), accel_(accel_steps_s2) {
  VDRIG_CHECK(steps >= 0, "step count must not be negative");
  VDRIG_CHECK(max_speed_steps_s > 0.0 && accel_steps_s2 > 0.0, "speed and acceleration must be positive");
  if (steps == 0) return;
  const double n = static_cast<double>(steps);
  const double full_accel_steps = max_speed_steps_s * max_speed_steps_s / (2.0 * accel_steps_s2);
  if (2.0 * full_accel_steps <= n) {  // trapezoid: reaches max speed
    peak_speed_ = max_speed_steps_s;
    accel_steps_ = full_accel_steps;
  } else {  // triangle: turns round half way
    accel_steps_ = n / 2.0;
    peak_speed_ = std::sqrt(n * accel_steps_s2);
  }
  accel_s_ = peak_speed_ / accel_steps_s2;
  total_s_ = 2.0 * accel_s_ + (n - 2.0 * accel_steps_) / peak_speed_;
}

double TrapezoidProfile::step_time_s(int64_t k) const {
  VDRIG_CHECK(k >= 1 && k <= steps_, "step index out of range");
  const double x = static_cast<double>(k);
  const double n = static_cast<double>(steps_);
  if (k == steps_) return total_s_;
  if (x <= accel_steps_) return std::sqrt(2.0 * x / accel_);
  if (x <= n - accel_steps_) return accel_s_ + (x - accel_steps_) / peak_speed_;
  return total_s_ - std::sqrt(2.0 * (n - x) / accel_);
}

double TrapezoidProfile::position_at(double t) const {
  t = std::clamp(t, 0.0, total_s_);
  const double n = static_cast<double>(steps_);
  if (t <= accel_s_) return 0.5 * accel_ * t * t;
  if (t <= total_s_ - accel_s_) return accel_steps_ + peak_speed_ * (t - accel_s_);
  const double r = total_s_ - t;
  return n - 0.5 * accel_ * r * r;
}

std::vector<double> TrapezoidProfile::step_times() const {
  std::vector<double> times;
  times.reserve(static_cast<size_t>(steps_));
  for (int64_t k = 1; k <= steps_; ++k) times.push_back(step_time_s(k));
  return times;
}

}  // namespace vdrig::rig

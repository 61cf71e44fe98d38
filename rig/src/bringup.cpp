// check_rig_config and run_self_test (bringup.hpp); list_devices is in bringup_devices.cpp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>

#include "vdrig/core/log.hpp"
#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/geometry_config.hpp"
#include "vdrig/rig/motion.hpp"

namespace vdrig::rig {
namespace {
using nlohmann::json;
constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;

std::string join(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

}  // namespace

ConfigCheck check_rig_config(const json& config, const BackendRegistry& registry) {
  ConfigCheck check;
  check.effective = json::object();
  check.problems = registry.top_level_problems(config);
  if (!config.is_object()) return check;
  const std::pair<const char*, std::vector<std::string>> kinds[] = {{"stage", registry.stage_backends()},
                                                                    {"camera", registry.camera_backends()},
                                                                    {"light", registry.light_backends()}};
  for (const auto& [kind, known] : kinds) {
    const bool optional = std::string(kind) == "light";
    if (!config.contains(kind)) {
      if (!optional) check.problems.push_back(std::string("no \"") + kind + "\" section");
      continue;
    }
    const json& section = config[kind];
    if (!section.is_object() || !section.contains("backend") || !section["backend"].is_string()) {
      check.problems.push_back(std::string("\"") + kind + "\" needs a \"backend\" name; known: " + join(known));
      continue;
    }
    const std::string backend = section["backend"].get<std::string>();
    if (std::find(known.begin(), known.end(), backend) == known.end()) {
      check.problems.push_back(std::string("unknown ") + kind + " backend \"" + backend +
                               "\" in this build; known: " + join(known));
      continue;
    }
    // The backend's own settings parser, supplied with its registration (BackendSpec::check).
    std::optional<json> effective;
    if (auto checked = registry.check_device_section(kind, backend, section)) {
      if (*checked)
        effective = checked->value();
      else
        check.problems.push_back(checked->error().message);
    }
    check.effective[kind] = effective ? *effective : section;
  }
  // Reported with the top level's problems when not valid.
  if (config.contains("geometry"))
    if (auto g = geometry_from_section(config["geometry"]))
      check.effective["geometry"] = geometry_section(g.value(), config["geometry"].value("source", ""));
  return check;
}

namespace {

using Clock = std::chrono::steady_clock;

SelfTestStep step(std::string name, bool passed, std::string detail) {
  return {std::move(name), passed, std::move(detail)};
}

std::string fmt(const char* format, double a, double b = 0, double c = 0, double d = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, format, a, b, c, d);
  return buf;
}

/// A small move to `target` (radians), timed and read back.
SelfTestStep test_move(PanTiltStage& stage, const std::string& name, const PanTilt& from, const PanTilt& target,
                       const SelfTestOptions& o) {
  const auto t0 = Clock::now();
  const Status moved = stage.move_to(target);
  const double took_s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (!moved) return step(name, false, moved.describe());
  auto at = stage.position();
  if (!at) return step(name, false, "position read-back failed: " + at.error().describe());
  const double pan_err = (at->pan_rad - target.pan_rad) * kDegPerRad;
  const double tilt_err = (at->tilt_rad - target.tilt_rad) * kDegPerRad;
  // A stage whose moves run faster than real time by design (the simulator's time_scale) is timed against its profile
  // scaled the same way: otherwise a simulated rig with time_scale 0 failed as "much faster than the profile".
  const double scale = stage.wall_time_scale();
  const double expected_s = move_time_s(stage.spec(), from, target) * scale;
  std::string detail = fmt("to (%.3f, %.3f) deg: read back error (%.4f, %.4f) deg", target.pan_rad * kDegPerRad,
                           target.tilt_rad * kDegPerRad, pan_err, tilt_err) +
                       fmt(", took %.3f s, profile %.3f s", took_s, expected_s) +
                       (scale != 1.0 ? fmt(" (time scale %g)", scale) : std::string());
  if (std::abs(pan_err) > o.position_tolerance_deg || std::abs(tilt_err) > o.position_tolerance_deg)
    return step(name, false, detail + fmt(": beyond the tolerance of %.4f deg", o.position_tolerance_deg));
  // Polling and settling add time, so only a move much faster than the profile, or far slower, is suspect: the
  // drive then used other speeds than the ones sent (a clamped or garbled profile register).
  if (took_s < 0.5 * expected_s - 0.02)
    return step(name, false,
                detail +
                    ": much faster than the configured profile (does the drive get the speeds "
                    "sent? word order, units)");
  if (took_s > 3.0 * expected_s + 1.0) return step(name, false, detail + ": much slower than the configured profile");
  return step(name, true, detail);
}

double clamp_step(const AxisSpec& a, double step_rad) {
  // A step away from 0 that stays within the axis limits (towards the side with more room).
  if (a.continuous) return step_rad;
  if (a.max_rad >= step_rad) return step_rad;
  if (a.min_rad <= -step_rad) return -step_rad;
  return 0.5 * (a.min_rad + a.max_rad);
}

}  // namespace

std::vector<SelfTestStep> run_self_test(Rig& rig, const SelfTestOptions& o) {
  std::vector<SelfTestStep> steps;
  PanTiltStage& stage = *rig.stage;
  {
    const auto t0 = Clock::now();
    const Status homed = stage.home();
    const double took = std::chrono::duration<double>(Clock::now() - t0).count();
    steps.push_back(homed ? step("home", true, fmt("%.3f s", took)) : step("home", false, homed.describe()));
    if (!homed) return steps;
  }
  auto home_pos = stage.position();
  if (!home_pos) {
    steps.push_back(step("position after home", false, home_pos.error().describe()));
    return steps;
  }
  const double home_err = std::max(std::abs(home_pos->pan_rad), std::abs(home_pos->tilt_rad)) * kDegPerRad;
  steps.push_back(step("position after home", home_err <= o.position_tolerance_deg,
                       fmt("(%.4f, %.4f) deg", home_pos->pan_rad * kDegPerRad, home_pos->tilt_rad * kDegPerRad)));
  const StageSpec spec = stage.spec();
  const double move_rad = o.move_deg / kDegPerRad;
  const PanTilt zero{};
  const PanTilt pan_only{clamp_step(spec.pan, move_rad), 0.0};
  const PanTilt both{pan_only.pan_rad, clamp_step(spec.tilt, move_rad)};
  const std::pair<const char*, std::pair<PanTilt, PanTilt>> moves[] = {
      {"move pan", {zero, pan_only}}, {"move tilt", {pan_only, both}}, {"move back home", {both, zero}}};
  for (const auto& [name, m] : moves) {
    steps.push_back(test_move(stage, name, m.first, m.second, o));
    if (!steps.back().passed) {
      (void)stage.stop();
      return steps;
    }
  }

  Camera& camera = *rig.camera;
  auto info = camera.info();
  if (!info) {
    steps.push_back(step("camera info", false, info.error().describe()));
    return steps;
  }
  steps.push_back(step("camera info", !info->auto_exposure_on,
                       info->model + " " + std::to_string(info->width) + "x" + std::to_string(info->height) + ", " +
                           std::to_string(info->bits) + " bit" +
                           (info->auto_exposure_on ? ": auto exposure is on (a bracket needs it off)" : "")));
  double previous_mean = -1.0;
  for (const double exposure_s : o.exposures_s) {
    const std::string name = fmt("frame at %.4g s", exposure_s);
    if (Status s = camera.set_exposure(exposure_s, 1.0); !s) {
      steps.push_back(step(name, false, s.describe()));
      continue;
    }
    auto frame = camera.capture();
    if (!frame) {
      steps.push_back(step(name, false, frame.error().describe()));
      continue;
    }
    if (frame->image.empty()) {
      steps.push_back(step(name, false, "empty image"));
      continue;
    }
    const double full = std::pow(2.0, frame->bits) - 1.0;
    cv::Scalar mean = cv::mean(frame->image);
    const double level = (mean[0] + mean[1] + mean[2]) / 3.0 / full;
    // Longer exposure, brighter picture, unless it is already (nearly) saturated.
    const bool brighter = previous_mean < 0 || level >= previous_mean * 0.98 || previous_mean > 0.95;
    steps.push_back(step(name, brighter,
                         std::to_string(frame->image.cols) + "x" + std::to_string(frame->image.rows) +
                             fmt(", mean level %.3f of full scale, exposure used %.4g s", level, frame->exposure_s) +
                             (brighter ? "" : ": darker than the shorter exposure before it")));
    previous_mean = level;
  }
  if (rig.light) {
    const Status on = rig.light->set_on(true);
    const Status off = rig.light->set_on(false);
    steps.push_back(step("light on/off", on && off, on ? (off ? "switched" : off.describe()) : on.describe()));
  }
  return steps;
}

}  // namespace vdrig::rig

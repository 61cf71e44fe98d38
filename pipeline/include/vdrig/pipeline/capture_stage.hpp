// Capture stage: plan the views of a scheme on a rig and capture them into a new session folder.
#pragma once

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/capture/session.hpp"

namespace vdrig::pipeline {

struct CaptureRequest {
  std::filesystem::path out_dir;
  nlohmann::json rig_config;         // e.g. sim::sim_rig_config({{"scene", "patchwork"}})
  std::string scheme = "latlong:6";  // see capture/schemes.hpp
  std::vector<double> exposures_s = {0.25};
  std::function<void(int done, int total)> on_view;
  nlohmann::json manifest_extra = nlohmann::json::object();  // the manifest's `extra` section, e.g. who made it
};

/// Plans the views (scheme -> inverse kinematics; unreachable directions logged), creates the session and captures
/// on a rig of sim::simulator_and_hardware_backends().
/// The views are aimed with the config's "geometry" section when it has one (capture::geometry_from_rig_config),
/// else, for a simulated rig, with the simulator's ground truth (unlike `vdrig capture`, which never plans with the
/// hidden truth: this makes reference sessions whose views land exactly where planned), else the ideal rig. The
/// surface size comes from the simulator's ground truth for a simulated rig, a hardware rig gets capture::Manifest's
/// defaults.
Result<capture::Session> capture_session(const CaptureRequest& request);

}  // namespace vdrig::pipeline

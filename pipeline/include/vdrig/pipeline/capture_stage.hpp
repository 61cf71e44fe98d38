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
/// The views are aimed as `vdrig capture` aims them: with the config's "geometry" section when it has one
/// (capture::geometry_from_rig_config), else the ideal rig at the configured distance (never the simulator's hidden
/// geometry). The surface size comes from the simulated scene for a simulated rig (the sample's size, part of the
/// rig's configuration); a hardware rig gets capture::Manifest's defaults.
Result<capture::Session> capture_session(const CaptureRequest& request);

}  // namespace vdrig::pipeline

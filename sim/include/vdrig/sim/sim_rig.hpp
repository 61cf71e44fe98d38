// The simulated rig: a PanTiltStage, a Camera and a Light behind the same interfaces as the hardware, sharing one
// SimWorld (the platform's pose, the scene on it, the fixed camera). It is the default backend ("sim").
//
// Rig config section "sim" (edges in degrees, mm, seconds):
//   { "scene": "patchwork", "distance_mm": 2500, "samples_per_axis": 2, "time_scale": 0 (0 = moves take no time,
//     1 = real time), "seed": 1,
//     "camera": { "width": 640, "height": 480, "fx": 800, "fy": 800, "cx": 319.5, "cy": 239.5,
//                 "k1": -0.08, "k2": 0.02, "p1": 0, "p2": 0, "k3": 0, "bits": 8,
//                 "response": "s-curve" | "linear", "full_well_e": 0, "read_noise_e": 0, "vignetting": 0 },
//     "stage": { "pan_min_deg": -360, "pan_max_deg": 360, "tilt_min_deg": -5, "tilt_max_deg": 85,
//                "speed_deg_s": 30, "accel_deg_s2": 60 } }
#pragma once

#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>

#include "vdrig/rig/kinematics.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {

struct SimConfig {
  std::string scene = "patchwork";
  CameraModel camera{640, 480, 800.0, 800.0, 319.5, 239.5, -0.08, 0.02, 0.0, 0.0, 0.0};
  SensorSettings sensor;
  rig::RigGeometry geometry;
  rig::StageSpec stage;
  int samples_per_axis = 2;
  double time_scale = 0.0;

  SimConfig();
  /// Reads the "sim" section; unknown keys are rejected so a typo does not silently fall back to a default.
  static Result<SimConfig> from_json(const nlohmann::json& section);
  bool is_valid(std::string* why) const;
};

/// State shared by the simulated devices of one rig.
struct SimWorld {
  SimConfig config;
  Scene scene;
  std::mutex mutex;
  PanTilt position;        // current platform position
  bool homed = false;
  uint64_t frame_sequence = 0;
  double exposure_s = 0.01;
  double gain = 1.0;
  bool light_on = true;

  ViewPose pose() const { return rig::surface_pose(config.geometry, position); }
};

/// Adds the "sim" stage, camera and light backends.
void register_backends(rig::BackendRegistry& registry);

/// A rig config that selects the simulator for every device, with the given "sim" section.
nlohmann::json sim_rig_config(const nlohmann::json& sim_section = nlohmann::json::object());

/// Time of a trapezoidal-profile move of `distance` at `max_speed` and `accel` (triangular when too short).
double trapezoid_time_s(double distance, double max_speed, double accel);

}  // namespace vdrig::sim

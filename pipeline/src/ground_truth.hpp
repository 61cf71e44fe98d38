// GroundTruth: what a simulated rig knows exactly and a real rig has to calibrate. The one place in pipeline/ that
// reads the simulator's configuration (sim::SimConfig); every stage asks ground_truth_of() instead.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::pipeline {

struct GroundTruth {
  CameraModel camera;           // intrinsics and distortion of the simulated camera
  rig::RigGeometry geometry;    // the stage's kinematics: measured pan/tilt -> surface pose
  ResponseCurve response;       // the simulated sensor's response curve
  calib::MarkerLayout markers;  // the scene's registration markers
  double surface_width_mm = 0.0, surface_height_mm = 0.0;

  /// The exact surface pose of a view taken at `measured` pan/tilt.
  ViewPose pose_at(const PanTilt& measured) const { return rig::surface_pose(geometry, measured); }
};

/// The ground truth of a rig config with a "sim" section, nullopt for any other (hardware) rig. An invalid "sim"
/// section or an unknown scene is the simulator's error.
Result<std::optional<GroundTruth>> ground_truth_of(const nlohmann::json& rig_config);

}  // namespace vdrig::pipeline

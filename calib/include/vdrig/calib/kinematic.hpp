// Kinematic calibration of the pan/tilt rig: the RigGeometry (camera distance, surface offset) that best explains
// the per-view extrinsics measured from the markers at the stage's read-back pan/tilt.
//
// Model (rig/kinematics.hpp): t = R_cw R_ws(pan, tilt) offset + (0, 0, D), R = R_cw R_ws. The translation is linear
// in (offset, D), so the fit is linear least squares on the translations (Eigen, column-pivoting QR; every view
// weighs the same, mm residuals). The rotation does not depend on these parameters: its departure from the model is
// reported per view (axis zero or alignment errors of the real rig show there) but not fitted.
#pragma once

#include <nlohmann/json.hpp>
#include <span>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::calib {

struct KinematicObservation {
  int view = 0;
  PanTilt measured;  // stage read-back
  ViewPose pose;     // from the markers
};

/// How far one view's measured pose is from the fitted model's pose at its pan/tilt.
struct KinematicResidual {
  int view = 0;
  double rotation_deg = 0.0;      // angle of R_measured R_model^T
  double translation_mm = 0.0;    // |t_measured - t_model|
  double camera_centre_mm = 0.0;  // distance between the camera centres (surface frame)
};

struct KinematicFit {
  rig::RigGeometry geometry;
  std::vector<KinematicResidual> residuals;  // one per observation, input order
  double rms_translation_mm = 0.0;
  double rms_rotation_deg = 0.0;
  double max_rotation_deg = 0.0;

  nlohmann::json to_json() const;
  /// The geometry part of to_json() (camera_distance_mm, surface_offset_mm).
  static Result<rig::RigGeometry> geometry_from_json(const nlohmann::json& j);
};

/// Fits camera distance and surface offset. Needs >= 2 observations with different platform rotations
/// (kInvalidArgument otherwise, or when the system is rank deficient, e.g. all views at one pan/tilt).
Result<KinematicFit> fit_rig_geometry(std::span<const KinematicObservation> observations);

/// Residuals of a given geometry (no fit).
std::vector<KinematicResidual> kinematic_residuals(const rig::RigGeometry& geometry,
                                                   std::span<const KinematicObservation> observations);

}  // namespace vdrig::calib

// Kinematic calibration of the pan/tilt rig: the RigGeometry that best explains the per-view extrinsics measured
// from the markers at the stage's read-back pan/tilt (encoder readings).
//
// The model (rig/kinematics.hpp, rig/kinematics_model.hpp) has 8 parameters: camera distance D, surface offset o
// (3), the encoder zeros of pan and tilt, and the two angles of the pan axis's tilt against the surface normal.
// Per view it predicts R = R_cw Rx(tilt_r - tilt_zero) Rz(pan_r - pan_zero) A and
// t = R_cw (Rx(..) Rz(..) o - (0, 0, D)).
//
// The fit (fit_rig_geometry):
//  1. start: the linear least-squares fit of (o, D) on the translations with the ideal rotation (Eigen QR, rank
//     checked), then a start for pan zero and axis tilt from the chordal mean of Rz(pan_r)^T Rx(tilt_r)^T R_cw R
//     over the views (tilt zero starts at 0);
//  2. Ceres Levenberg-Marquardt with automatic derivatives of the model on 6 residuals a view: the rotation
//     vector of R_measured R_model^T (camera frame, rad) and t_measured - t_model (mm). Weighting: the residuals
//     fall in four groups of different noise: rotation about the image axes x, y and about the optical axis z,
//     translation across the image and along the optical axis (a marker pose's depth is several times worse
//     than its lateral position). Each group is divided by its own noise sigma, estimated from the group's residuals
//     (sum of squares / (n_group (1 - 8 / n_residuals))) and the fit repeated with the new weights (4 rounds),
//     so that weighted residuals have unit variance. A view whose weighted squared residuals sum beyond 16 (a
//     chi-square of 6 degrees of freedom passes that 1.4 % of the time; a near-grazing view posed 0.1 deg off
//     does) weighs through Huber's loss, and is left out of the noise estimate;
//  3. the parameters' standard deviations from the covariance of the weighted fit (ceres::Covariance, dense SVD),
//     scaled by the reduced chi-square. They are the noise's share only: a bias common to the marker poses (about
//     0.01 deg on the simulator) does not show in them.
// Views that cannot determine the parameters (all at one pan, all at tilt 0, or too few) give a kInvalidArgument naming
// the undetermined combination, from the rank of the column-scaled Jacobian at the solution.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/rig/kinematics_model.hpp"

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
  /// Standard deviation of each parameter, in rig::model::Param order and units (mm, rad); nullopt when the
  /// covariance could not be computed (the fit itself stands, and says so in the log and the JSON).
  std::optional<rig::model::Params> sigma;
  /// The noise the residual groups were weighted by (the fit's own estimate, see above).
  double noise_rotation_xy_deg = 0.0, noise_rotation_z_deg = 0.0;
  double noise_translation_xy_mm = 0.0, noise_translation_z_mm = 0.0;
  /// Views (KinematicObservation::view) whose residuals were beyond a chi-square of 16 and so weighed less.
  std::vector<int> downweighted_views;
  std::vector<KinematicResidual> residuals;  // one per observation, input order
  double rms_translation_mm = 0.0;
  double rms_rotation_deg = 0.0;
  double max_rotation_deg = 0.0;

  /// The geometry (geometry_to_json's keys), "sigma" (the same keys, or null), "noise", rms and per-view residuals.
  nlohmann::json to_json() const;
  /// camera_distance_mm, surface_offset_mm [3], pan_zero_deg, tilt_zero_deg, pan_axis_tilt_x_deg,
  /// pan_axis_tilt_y_deg. Both are rig::kinematics_to_json / kinematics_from_json (rig/geometry_config.hpp), which
  /// capture uses to plan with a fit without depending on calib.
  static nlohmann::json geometry_to_json(const rig::RigGeometry& geometry);
  /// The geometry part of to_json(). The distance and offset are required; a missing angle is 0 (files written
  /// before the full model read as the ideal rig they were fitted as). kCorrupt on wrong types or values.
  static Result<rig::RigGeometry> geometry_from_json(const nlohmann::json& j);
};

/// Fits all 8 parameters (see above). Needs >= 2 observations (kInvalidArgument otherwise, or when the views do
/// not determine the parameters, e.g. all at one pan/tilt).
Result<KinematicFit> fit_rig_geometry(std::span<const KinematicObservation> observations);

/// Residuals of a given geometry (no fit).
std::vector<KinematicResidual> kinematic_residuals(const rig::RigGeometry& geometry,
                                                   std::span<const KinematicObservation> observations);

}  // namespace vdrig::calib

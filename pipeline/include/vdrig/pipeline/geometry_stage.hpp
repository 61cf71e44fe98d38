// Geometry stage: the camera and per-view poses of a session, and their calibration from the corner markers.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/calib/intrinsics.hpp"
#include "vdrig/calib/kinematic.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

/// Camera and per-view poses of a session, from what calibration wrote in SESSION/calib/ (camera.yml and views.json,
/// `vdrig calib extrinsics`): never from the simulator's configuration, a simulated session is calibrated from its
/// images as a real one. A view with a marker pose that passed the reprojection threshold uses it; any other view
/// (excluded, or markers not found) is posed by the fitted rig kinematics (the full model: distance, offset, encoder
/// zeros, pan-axis tilt; views.json written before it has no angles) at its measured pan/tilt, flagged
/// `kinematic_pose`, and kept unless views.json says exclude_unposed (then flagged `excluded` too, and the
/// observation map flags its observations kObsExcluded); without a kinematic fit in views.json such a view is
/// kNotFound. A session without calib/ is kNotFound naming the command to run.
struct SessionGeometry {
  CameraModel camera;
  std::vector<ViewPose> poses;        // per planned view
  std::vector<bool> kinematic_pose;   // per planned view: posed by the kinematic fit (no usable marker pose)
  std::vector<bool> excluded;         // per planned view: left out of the observation map
  std::string source = "calibrated";  // where the geometry came from, for the log (SESSION/calib/)
};
Result<SessionGeometry> session_geometry(const capture::Session& session);

/// Geometric calibration of a session from its corner markers (calib/extrinsics.hpp, calib/kinematic.hpp).
struct GeometryCalibrationOptions {
  /// Camera model (intrinsics, e.g. from `vdrig calib intrinsics`). When unset: SESSION/calib/camera.yml, else
  /// kNotFound naming the command that makes one.
  std::optional<CameraModel> camera;
  /// Marker layout; unset: 30 mm discs 50 mm in from each corner of the manifest's surface size (the layout of every
  /// built-in scene).
  std::optional<calib::MarkerLayout> layout;
  double max_error_px = 1.0;  // views above this RMS reprojection error are excluded
  bool fit_kinematics = true;
  /// Recorded in views.json: views without a usable marker pose are left out of the observation map instead of
  /// being posed by the kinematic fit.
  bool exclude_unposed = false;
};
struct GeometryCalibration {
  CameraModel camera;
  calib::ViewsFile views;                         // as written to SESSION/calib/views.json
  std::optional<calib::KinematicFit> kinematics;  // when >= 2 usable views (and asked for)
  int usable_views = 0;
};
/// Merges missing HDR views (merge_session_hdr), detects the markers in every complete view's HDR image (rough pose:
/// the nominal rig model, i.e. the rig config's camera distance without surface offset, at the measured pan/tilt),
/// solves each view's pose, fits the rig kinematics to the usable views, and writes SESSION/calib/camera.yml and
/// SESSION/calib/views.json (atomically). A view whose markers are not found is recorded with the reason, not an
/// error; no usable view at all is kNotFound.
Result<GeometryCalibration> calibrate_session_geometry(const capture::Session& session,
                                                       const GeometryCalibrationOptions& options = {});

/// Camera intrinsics from a session of a chessboard (e.g. `vdrig capture --scene chessboard`): per complete view,
/// the frame of the longest exposure with at most max_saturated_fraction of its pixels at the top code (the board's
/// white squares clipped would shift the corners; a darker frame is noisier), then calib::calibrate_intrinsics.
struct SessionIntrinsicsOptions {
  int board_cols = 8, board_rows = 6;  // inner corners
  double square_m = 0.160;
  double max_saturated_fraction = 0.005;
  calib::IntrinsicsOptions intrinsics;
};
Result<calib::IntrinsicsResult> calibrate_session_intrinsics(const capture::Session& session,
                                                             const SessionIntrinsicsOptions& options = {});

}  // namespace vdrig::pipeline

// Geometry stage: the camera and per-view poses of a session, and their calibration from the corner markers.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/calib/kinematic.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

/// Camera and per-view poses of a session: from SESSION/calib/ when calibrated (camera.yml and views.json both
/// present), else the simulator's ground truth. Calibrated: a view with a marker pose that passed the reprojection
/// threshold uses it; any other view (excluded, or markers not found) is posed by the fitted rig kinematics (the
/// full model: distance, offset, encoder zeros, pan-axis tilt; views.json written before it has no angles) at its
/// measured pan/tilt and flagged `excluded` (the observation map flags its observations kObsExcluded); without a
/// kinematic fit in views.json such a view is kNotFound.
struct SessionGeometry {
  CameraModel camera;
  std::vector<ViewPose> poses;  // per planned view
  std::vector<bool> excluded;   // per planned view: no usable marker pose (calibrated sessions only)
  std::string source;           // "calibrated" or "simulator ground truth"
};
Result<SessionGeometry> session_geometry(const capture::Session& session);

/// Geometric calibration of a session from its corner markers (calib/extrinsics.hpp, calib/kinematic.hpp).
struct GeometryCalibrationOptions {
  /// Camera model (intrinsics, e.g. from `vdrig calib intrinsics`). When unset: SESSION/calib/camera.yml if present,
  /// else, for a simulated session, the simulator's camera (a simulated session has no chessboard views of its own;
  /// logged as a warning), else kNotFound.
  std::optional<CameraModel> camera;
  /// Marker layout; unset: the simulator scene's markers, else 30 mm discs 50 mm in from each corner of the
  /// manifest's surface size.
  std::optional<calib::MarkerLayout> layout;
  double max_error_px = 1.0;  // views above this RMS reprojection error are excluded
  bool fit_kinematics = true;
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

}  // namespace vdrig::pipeline

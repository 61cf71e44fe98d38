// The stages of vdrig chained on a session folder. Each stage reads what the previous one wrote, so each can be
// run alone (vdrig hdr / obsmap / fit / render) or all at once (vdrig demo).
//
//   SESSION/hdr/view_VVVV.exr     merged bracket of each view (calib::HdrImage)
//   SESSION/obsmap/SxT.vdobs      observation maps (fitting/obsmap_file.hpp), kept for further fits
//   SESSION/maps/<model>.exr      parameter maps (fitting::ParameterMap)
//   SESSION/renders/              headless renders, photographs and difference images
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/calib/kinematic.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::pipeline {

/// A registry with every backend of this build: the simulator and the hardware compiled in.
rig::BackendRegistry full_registry();

struct CaptureRequest {
  std::filesystem::path out_dir;
  nlohmann::json rig_config;         // e.g. sim::sim_rig_config({{"scene", "patchwork"}})
  std::string scheme = "latlong:6";  // see capture/schemes.hpp
  std::vector<double> exposures_s = {0.25};
  std::function<void(int done, int total)> on_view;
};

/// Plans the views (scheme -> inverse kinematics; unreachable directions logged), creates the session and captures.
Result<capture::Session> capture_session(const CaptureRequest& request);

/// Merges every view's bracket into SESSION/hdr/view_VVVV.exr with the session's response curve; views already
/// merged are skipped (resumable). The response comes from the sim config (ground truth) until radiometric
/// calibration writes SESSION/calib/response.json, which then takes precedence.
Status merge_session_hdr(const capture::Session& session);

/// Camera and per-view poses of a session: from SESSION/calib/ when calibrated (camera.yml and views.json both
/// present), else the simulator's ground truth. Calibrated: a view with a marker pose that passed the reprojection
/// threshold uses it; any other view (excluded, or markers not found) is posed by the fitted rig kinematics at its
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

/// Builds the observation map of a session in memory (views listed in `views`, or all when empty; view i of the map
/// is views[i]). Needs S x T x views x 25 B: for small maps (tests, the demo). Large maps: build_session_obsmap_file.
Result<fitting::ObservationMap> build_session_obsmap(const capture::Session& session, int texels_s, int texels_t,
                                                     const std::vector<int>& views = {});

struct ObsMapBuildOptions {
  std::vector<int> views;  // session view indices; empty = every view of the manifest. View i of the file = views[i].
  fitting::ObsFileOptions file;
  std::function<void(int done, int total)> on_view;
};
/// Streams the session's HDR views into an observation-map file (fitting/obsmap_file.hpp, docs/obsmap.md): one HDR
/// image and one view's observations in memory at a time, so any resolution builds with bounded memory. Nothing is
/// at `path` unless it succeeds. Errors: an unreadable HDR view (kNotFound/kCorrupt: run `vdrig hdr` first), a full
/// disk (kNoSpace), invalid sizes (kInvalidArgument).
Status build_session_obsmap_file(const capture::Session& session, int texels_s, int texels_t,
                                 const std::filesystem::path& path, const ObsMapBuildOptions& options = {});

/// SESSION/obsmap/<S>x<T>.vdobs over every view, built (build_session_obsmap_file) unless a file is there that is
/// still current: same size and view count, and newer than every HDR view and the geometric calibration (calib/),
/// so fitting several models at one resolution samples the views once. Returns the file's path.
Result<std::filesystem::path> session_obsmap_file(const capture::Session& session, int texels_s, int texels_t,
                                                  const ObsMapBuildOptions& options = {});

/// Renders the map from a session view's pose; writes render, photograph and |difference| PNGs to out_dir and
/// returns the mean absolute difference in 8-bit code units over `region` (non-zero pixels), or all pixels.
struct Comparison {
  double mean_abs_error = 0;
  std::filesystem::path render_png, photo_png, diff_png;
};
Result<Comparison> render_and_compare(const capture::Session& session, const fitting::ParameterMap& map, int view,
                                      const std::filesystem::path& out_dir, const cv::Mat& region = {});

}  // namespace vdrig::pipeline

namespace vdrig::pipeline {

/// Pixels (CV_8UC1, 255) whose ray meets the surface inside the rectangle [x0, x1] x [y0, y1] mm (surface frame).
cv::Mat surface_region_mask(const CameraModel& camera, const ViewPose& pose, double x0_mm, double y0_mm, double x1_mm,
                            double y1_mm);

}  // namespace vdrig::pipeline

// Per-view extrinsics from the four round corner markers of the surface: detection near the markers' predicted
// images (a rough pose, e.g. the commanded pan/tilt through rig kinematics), sub-pixel area centroids, and the pose
// by cv::solvePnP (IPPE, then Levenberg-Marquardt) with a correction of the centroid bias (the image of a disc's
// centre is not the centroid of the disc's image under perspective and distortion).
//
// SESSION/calib/views.json (format_version 1), written by write_views_json:
//   { "format_version": 1, "camera": "camera.yml", "max_error_px": 1.0,
//     "marker_radius_mm": 30, "marker_centres_mm": [[x, y, z], ...],
//     "views": [ { "index": 0, "pan_deg": .., "tilt_deg": .., "ok": true,
//                  "rvec": [3] (Rodrigues, rad), "tvec_mm": [3], "reprojection_error_px": 0.01,
//                  "excluded": false, "markers_px": [[u, v] x4] }            // an ok view
//                { "index": 1, "ok": false, "excluded": true, "error": "..." } ],   // detection failed
//     "kinematics": { "camera_distance_mm": .., "surface_offset_mm": [3], ... } }   // optional (kinematic.hpp)
// The pose convention is vdrig's (docs/conventions.md): p_cam = R(rvec) p_surface + tvec.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::calib {

inline constexpr int kViewsFormatVersion = 1;

/// Where the markers are on the surface. The order of `centres_mm` is the markers' identity: detection returns
/// one image point per entry, in this order.
struct MarkerLayout {
  std::vector<Vec3d> centres_mm;  // surface frame, z = 0
  double radius_mm = 30.0;

  /// Four discs centred `inset_mm` in from each corner of a W x H surface, in the simulator's order:
  /// (-x, -y), (+x, -y), (+x, +y), (-x, +y).
  static MarkerLayout corners(double width_mm, double height_mm, double inset_mm = 50.0, double radius_mm = 30.0);
  bool is_valid(std::string* why) const;
};

struct MarkerDetectionOptions {
  /// Half size of the square searched around each predicted marker image, pixels; 0 = automatic
  /// (max(3 x the predicted radius, predicted radius + 25 px)): covers rough poses a few degrees / tens of mm off.
  double search_half_px = 0.0;
  /// A marker must be at least this much darker than its surroundings (1 - dark / background).
  double min_contrast = 0.5;
  /// Accepted blob area as a ratio of the predicted disc image's area.
  double min_area_ratio = 0.3, max_area_ratio = 3.0;
  /// Accepted ratio of the blob's area to that of the ellipse with its second moments (1 for an ellipse).
  double min_ellipse_fill = 0.7, max_ellipse_fill = 1.3;
};

/// Finds each marker of `layout` in `image` near where `rough_pose` projects it, and returns the area centroid of
/// its image (pixels, OpenCV convention) in layout order. The image is linear radiance (CV_32FC1/3, best: the
/// centroid weights are coverage fractions) or camera codes (CV_8U/CV_16U, 1 or 3 channels; a non-linear response
/// biases partial pixels slightly). Centroid: the dark blob (threshold midway between the window's background
/// and darkest level, connected components, area and ellipse-fill checks, nearest to the prediction) grown by
/// 2 px; each pixel weighs its coverage (bg - I) / (bg - dark), bg a plane fitted to a ring around the blob.
/// Errors (kNotFound, naming the markers and why): a marker projecting outside the image, no dark blob of the
/// right size and shape (blank or occluded), too little contrast. kInvalidArgument: empty/unsupported image,
/// invalid camera or layout.
Result<std::vector<Vec2d>> detect_markers(const cv::Mat& image, const CameraModel& camera, const ViewPose& rough_pose,
                                          const MarkerLayout& layout, const MarkerDetectionOptions& options = {});

/// Area centroid of the image of a disc (centre `centre_mm`, in the surface plane) seen at `pose`: the shoelace
/// centroid of its projected boundary (distortion included), 256 boundary points.
Vec2d projected_disc_centroid(const CameraModel& camera, const ViewPose& pose, const Vec3d& centre_mm,
                              double radius_mm);

struct ExtrinsicsOptions {
  double max_error_px = 1.0;          // views with a larger RMS reprojection error are flagged excluded
  bool correct_centroid_bias = true;  // iterate: subtract (disc centroid - projected centre) at the current pose
  int bias_iterations = 4;
};

struct ViewExtrinsics {
  ViewPose pose;
  double reprojection_error_px = 0.0;  // RMS over the markers of |model disc centroid - measured centroid|
  bool excluded = false;               // reprojection_error_px > max_error_px
  std::vector<Vec2d> markers_px;       // measured centroids
};

/// The pose from the measured marker centroids (layout order). Errors: kInvalidArgument (count mismatch, fewer
/// than 4 markers, invalid camera), kInternal when solvePnP finds no pose with the surface in front of the camera.
Result<ViewExtrinsics> solve_view_extrinsics(const std::vector<Vec2d>& markers_px, const CameraModel& camera,
                                             const MarkerLayout& layout, const ExtrinsicsOptions& options = {});

/// detect_markers + solve_view_extrinsics.
Result<ViewExtrinsics> calibrate_view(const cv::Mat& image, const CameraModel& camera, const ViewPose& rough_pose,
                                      const MarkerLayout& layout, const MarkerDetectionOptions& detection = {},
                                      const ExtrinsicsOptions& options = {});

/// One view's entry of views.json: a solved pose, or why there is none.
struct ViewRecord {
  int index = 0;
  PanTilt measured;  // the stage's read-back position of the view
  std::optional<ViewExtrinsics> extrinsics;
  std::string error;  // when no extrinsics
  bool usable() const { return extrinsics && !extrinsics->excluded; }
};

struct ViewsFile {
  std::string camera_file = "camera.yml";
  double max_error_px = 1.0;
  /// Views without a usable marker pose are left out of the observation map (true), or kept, posed by the fitted
  /// kinematics (false, the default: grazing views whose markers leave the frame still carry reflectance).
  bool exclude_unposed = false;
  MarkerLayout layout;
  std::vector<ViewRecord> views;
  nlohmann::json kinematics;  // null, or the fitted rig model (kinematic.hpp's to_json)
};

nlohmann::json to_json(const ViewsFile& file);
Result<ViewsFile> views_from_json(const nlohmann::json& j);
/// Atomic write / read of views.json (kCorrupt on a bad or newer file).
Status write_views_json(const std::filesystem::path& path, const ViewsFile& file);
Result<ViewsFile> read_views_json(const std::filesystem::path& path);

/// Rodrigues vector <-> rotation matrix.
Vec3d rotation_to_rvec(const Mat3d& R);
Mat3d rvec_to_rotation(const Vec3d& rvec);

}  // namespace vdrig::calib

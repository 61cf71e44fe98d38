// CameraModel (OpenCV pinhole + Brown-Conrady) and ViewPose (p_cam = R p_surface + t), OpenCV conventions:
// camera x right, y down, z forward; pixel (0, 0) is the centre of the top-left pixel.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace cv {
class FileStorage;
}

namespace vdrig {

/// Intrinsics of a camera: focal lengths and principal point in pixels, distortion (k1, k2, p1, p2, k3),
/// and the image size the intrinsics belong to.
struct CameraModel {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;

  bool has_distortion() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0 || k3 != 0; }

  /// Applies distortion to normalised pinhole coordinates (x/z, y/z).
  Vec2d distort(const Vec2d& undistorted) const;
  /// Inverts distort() by fixed-point iteration (exact to ~1e-10 for realistic lenses).
  Vec2d undistort(const Vec2d& distorted) const;

  /// Projects a point in the camera frame to pixel coordinates (distortion applied). z must be > 0.
  Vec2d project(const Vec3d& p_cam) const;
  /// Unit ray in the camera frame through pixel (u, v) (distortion removed).
  Vec3d pixel_ray(const Vec2d& pixel) const;

  /// Checks the model is usable (positive size and focal lengths, principal point inside the image).
  bool is_valid(std::string* why) const;

  /// Reads/writes OpenCV-compatible YAML (camera_matrix, distortion_coefficients, image_width, image_height).
  /// `extras`, if set, writes further top-level entries into the same file (e.g. calib's per-view errors and
  /// standard deviations), after the model's.
  static Result<CameraModel> load_yaml(const std::filesystem::path& path);
  Status save_yaml(const std::filesystem::path& path, double avg_reprojection_error_px = -1,
                   const std::function<void(cv::FileStorage&)>& extras = {}) const;
};

/// Pose of the surface in a camera: p_cam = R p_surface + t (t in mm).
struct ViewPose {
  Mat3d R = Mat3d::Identity();
  Vec3d t = Vec3d::Zero();

  /// Camera centre in the surface frame: -R^T t.
  Vec3d camera_centre() const { return -R.transpose() * t; }
  Vec3d to_camera(const Vec3d& p_surface) const { return R * p_surface + t; }
  /// Unit direction from a surface point toward the camera, in the surface frame.
  Vec3d view_direction(const Vec3d& p_surface) const { return (camera_centre() - p_surface).normalized(); }
};

}  // namespace vdrig

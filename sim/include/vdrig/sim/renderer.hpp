// Rendering of a scene as the simulated camera sees it, and the camera's sensor model.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {

/// The undistorted rays (camera frame, unit) of a camera's pixel samples: samples_per_axis^2 stratified samples
/// per pixel at ((x - 0.5 + (sx + 0.5) / n), (y - 0.5 + (sy + 0.5) / n)). Building it is the costly part of a
/// render (one iterative undistortion per sample), so the simulated camera builds it once and keeps it.
class RayTable {
 public:
  RayTable(const CameraModel& camera, int samples_per_axis);
  const CameraModel& camera() const { return camera_; }
  int samples_per_axis() const { return n_; }
  /// Whether this table was built for exactly this camera and sampling.
  bool matches(const CameraModel& camera, int samples_per_axis) const;
  /// The n^2 rays of pixel (x, y), sample-row-major.
  const cv::Vec3f* rays(int x, int y) const { return &rays_[(static_cast<size_t>(y) * camera_.width + x) * n_ * n_]; }

 private:
  CameraModel camera_;
  int n_;
  std::vector<cv::Vec3f> rays_;
};

/// Renders the linear radiance image (CV_32FC3, BGR like every OpenCV colour image in vdrig) of `scene` seen by a
/// camera with intrinsics `camera` (distortion included) at `pose`. Each pixel averages
/// samples_per_axis^2 stratified rays over its footprint (antialiasing: edges and markers are sub-pixel accurate).
/// Pixels that miss the surface are black. Rows are rendered in parallel.
cv::Mat render_radiance(const Scene& scene, const CameraModel& camera, const ViewPose& pose, int samples_per_axis);
/// The same with a prebuilt ray table (camera and sampling are the table's).
cv::Mat render_radiance(const Scene& scene, const RayTable& rays, const ViewPose& pose);

/// The sensor of the simulated camera: exposure, response curve, noise, quantisation, saturation.
struct SensorSettings {
  ResponseCurve response = ResponseCurve::s_curve(8);
  double full_well_e = 0.0;   // electrons at saturation; 0 disables photon (Poisson) noise
  double read_noise_e = 0.0;  // read noise standard deviation in electrons (needs full_well_e > 0)
  double vignetting = 0.0;    // relative fall-off at the image corner: gain (1 - vignetting r^2 / r_corner^2)
  uint64_t seed = 1;

  bool is_valid(std::string* why) const;
};

/// Turns a radiance image into the 8/16-bit codes a camera delivers: X = radiance * exposure_s * gain (X = 1
/// saturates), then noise, then the response curve, rounding and clipping. Deterministic for (seed, sequence).
cv::Mat expose(const cv::Mat& radiance_bgr, double exposure_s, double gain, const SensorSettings& sensor,
               uint64_t sequence);

}  // namespace vdrig::sim

// ObservationMap: per texel of an S x T grid over the surface, every observed RGB radiance and the direction it was
// seen from (surface frame, unit, toward the camera), with a flag per observation.
//
// Building it (build_observation_map): texel centre (texel_centre_mm) -> surface point -> camera via the view's
// pose and intrinsics (distortion included) -> bilinear radiance sample of the view's HDR image -> direction to the
// camera centre. An observation is kept with a reason flag when it cannot be used.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::fitting {

enum ObservationFlag : uint8_t {
  kObsValid = 0,
  kObsOutside = 1,     // projects outside the image (or behind the camera)
  kObsBackFacing = 2,  // the camera is below the surface's horizon
  kObsClipped = 4,     // clipped in every exposure (HDR mask)
  kObsExcluded = 8,    // the view was excluded by calibration
  kObsOccluded = 16,   // covered by a marker or another known occluder
};

/// One view as the observation map consumes it: linear radiance (CV_32FC3, BGR), optional clip mask (CV_8UC1,
/// non-zero = clipped everywhere), the calibrated camera and the view's pose.
struct ViewInput {
  cv::Mat radiance_bgr;
  cv::Mat clip_mask;
  CameraModel camera;
  ViewPose pose;
  bool excluded = false;
};

/// Observations of one texel: parallel arrays over the views where the texel is valid.
struct TexelObservations {
  std::vector<Eigen::Vector3f> direction;  // unit, surface frame
  std::vector<Eigen::Vector3f> radiance;   // RGB
  std::vector<int> view;                   // view index of each observation
  size_t size() const { return direction.size(); }
};

struct ObservationMapSpec {
  int texels_s = 64;  // across the width (x)
  int texels_t = 64;  // across the height (y)
  double width_mm = 1000.0;
  double height_mm = 1000.0;

  bool is_valid(std::string* why) const;
};

/// In-memory observation map, texel-major: all views of a texel are contiguous.
class ObservationMap {
 public:
  ObservationMap(const ObservationMapSpec& spec, int views);

  const ObservationMapSpec& spec() const { return spec_; }
  int views() const { return views_; }

  /// Sets one observation (radiance RGB, direction) with its flag.
  void set(int s, int t, int view, const Eigen::Vector3f& rgb, const Eigen::Vector3f& direction, uint8_t flag);
  uint8_t flag(int s, int t, int view) const { return flags_[index(s, t, view)]; }
  /// The valid observations of texel (s, t), optionally leaving out the views in `held_out` (sorted).
  TexelObservations texel(int s, int t, const std::vector<int>& held_out = {}) const;
  /// One stored observation whatever its flag (radiance is zero where nothing was sampled); returns the flag.
  uint8_t observation(int s, int t, int view, Eigen::Vector3f* rgb, Eigen::Vector3f* direction) const;

 private:
  size_t index(int s, int t, int view) const { return (static_cast<size_t>(t) * spec_.texels_s + s) * views_ + view; }
  ObservationMapSpec spec_;
  int views_;
  std::vector<float> radiance_;   // 3 per observation
  std::vector<float> direction_;  // 3 per observation
  std::vector<uint8_t> flags_;
};

/// Samples one view into every texel of the map (view index `view`). Parallel over texel rows.
void add_view(ObservationMap& map, int view, const ViewInput& input);

/// The observation of texel (s, t) of a `spec` map in one view: radiance, direction toward the camera and flag.
/// add_view and the streaming file writer (obsmap_file.hpp) both use it, so both give identical observations.
/// `input.radiance_bgr` must be CV_32FC3.
uint8_t observe_texel(const ObservationMapSpec& spec, const ViewInput& input, int s, int t, Eigen::Vector3f* rgb,
                      Eigen::Vector3f* direction);

/// Bilinear sample of a CV_32FC3 BGR image at sub-pixel (x, y) (pixel centres at integers); false outside.
bool sample_bilinear(const cv::Mat& image_bgr, double x, double y, Eigen::Vector3f* rgb);

}  // namespace vdrig::fitting

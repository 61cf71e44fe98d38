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
  kObsCoarse = 32,     // the pixel's footprint on the surface is too wide (a grazing view): the sample mixes the
                       // texel's neighbours (kMaxFootprintTexels, observe_texel, docs/obsmap.md)
};

/// The widest footprint, in texels, of one image pixel on the surface that still makes an observation of the texel.
/// The bilinear sample at the texel centre blends the pixels within +-1 pixel, i.e. the surface within +-footprint of
/// the centre; at zenith z the footprint grows as 1 / cos(z) along the view's azimuth, so at 80-85 deg a sample reaches
/// two texels and more away and mixes in neighbouring materials (the edge of the surface, the next patch): on the
/// simulator's patchwork at 32x32 texels that biased Lambertian texels by 1-2 % relative RMS (docs/sampling.md,
/// "Grazing views").
inline constexpr double kMaxFootprintTexels = 1.0;
/// ... unless the texels are finer than the camera resolves square-on: a map finer than that (the default 256 x 256
/// with a 640 x 480 camera at 2.5 m) would lose every oblique view to kMaxFootprintTexels, so the footprint may also
/// reach this many times the square-on footprint from the same distance (distance / focal length): views beyond a
/// zenith of about 75 deg are then the ones dropped.
inline constexpr double kMaxFootprintStretch = 4.0;

/// The footprint of one image pixel on the surface at surface point `p_mm` (plane z = 0) in view (`camera`, `pose`):
/// the surface distance (mm) one pixel step spans along the image direction where it is longest (1 / the smallest
/// singular value of d(pixel) / d(surface)). +inf where the surface is seen edge-on or from behind.
double pixel_footprint_mm(const CameraModel& camera, const ViewPose& pose, const Vec3d& p_mm);

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
/// kObsCoarse (zero radiance, as every unusable observation) where pixel_footprint_mm exceeds both kMaxFootprintTexels
/// texel widths (the narrower of the texel's sides) and kMaxFootprintStretch times the square-on footprint.
/// add_view and the streaming file writer (obsmap_file.hpp) both use it, so both give identical observations.
/// `input.radiance_bgr` must be CV_32FC3.
uint8_t observe_texel(const ObservationMapSpec& spec, const ViewInput& input, int s, int t, Eigen::Vector3f* rgb,
                      Eigen::Vector3f* direction);

/// Bilinear sample of a CV_32FC3 BGR image at sub-pixel (x, y) (pixel centres at integers); false outside.
bool sample_bilinear(const cv::Mat& image_bgr, double x, double y, Eigen::Vector3f* rgb);

}  // namespace vdrig::fitting

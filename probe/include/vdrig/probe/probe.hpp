// Light probes: HDR radiance seen from one point in every direction, as a latitude-longitude map (docs/probe.md).
//
// Conventions (docs/conventions.md): column i of a W x H map looks at azimuth 2 pi (i + 0.5) / W (from +x
// toward +y), row j at zenith pi (j + 0.5) / H (row 0 looks along +z); row j's pixels subtend
// latlong_pixel_solid_angle(j, W, H) sr each. Directions here are in the probe's own frame unless a name says world.
//
// Channel order: images (cv::Mat) are B, G, R as everywhere in vdrig (OpenCV's order); colour triples in code
// (`Rgb`, Eigen) are R, G, B. Probe::pixel / set_pixel and to_bgr / from_bgr are the only places that cross over;
// files carry named channels R, G, B.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <opencv2/core.hpp>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::probe {

/// Linear RGB triple (radiance, irradiance or power; R, G, B in that order).
using Rgb = Eigen::Vector3d;

/// An Rgb as a pixel of a B, G, R float image, and back.
inline cv::Vec3f to_bgr(const Rgb& c) {
  return {static_cast<float>(c.z()), static_cast<float>(c.y()), static_cast<float>(c.x())};
}
inline Rgb from_bgr(const cv::Vec3f& v) { return {v[2], v[1], v[0]}; }

/// Relative luminance of linear RGB (Rec. 709 / sRGB primaries), the "energy" of the median cut.
inline double luminance(const Rgb& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

/// `Probe`: one light probe. A lat-long HDR radiance map in vdrig's layout (see the file comment), the
/// probe's pose in the world, and optionally the distance to the scene behind every pixel.
///  - radiance: CV_32FC3, H x W with W = 2 H, channels in B, G, R order (OpenCV's, as the rest of vdrig), linear,
///    >= 0; pixel() and set_pixel() convert to and from Rgb.
///  - position_mm: centre of the probe in the world (mm); rotation: probe frame -> world, d_world = R d_probe.
///  - depth_mm: CV_32FC1 of the same size, distance (mm) from position_mm along each pixel's direction to the
///    first surface; empty when unknown (a real probe photographed without a scene model).
struct Probe {
  cv::Mat radiance;
  Vec3d position_mm = Vec3d::Zero();
  Mat3d rotation = Mat3d::Identity();
  cv::Mat depth_mm;

  int width() const { return radiance.cols; }
  int height() const { return radiance.rows; }
  bool has_depth() const { return !depth_mm.empty(); }
  /// Radiance of pixel (i, j) (column, row). No bounds check beyond OpenCV's debug asserts.
  Rgb pixel(int i, int j) const { return from_bgr(radiance.at<cv::Vec3f>(j, i)); }
  void set_pixel(int i, int j, const Rgb& c) { radiance.at<cv::Vec3f>(j, i) = to_bgr(c); }
};

/// A W x H (W = 2 H) probe filled with zero radiance at the origin; VDRIG_CHECKs H >= 1.
Probe make_probe(int height);

/// How the columns of an equirectangular file map to azimuth.
enum class FileAzimuth {
  /// The usual panorama layout (HDRI Haven, Blender's equirectangular environment texture): seen from inside, the
  /// image runs left to right as the view turns right, i.e. clockwise seen from above. Blender maps direction d
  /// to u = 0.5 - atan2(d.y, d.x) / 2 pi, so the centre column looks along +x. Loading mirrors the columns so the
  /// probe frame is Blender's world frame: vdrig column i = (W / 2 - 1 - c) mod W for file column c.
  kPanorama,
  /// Already in vdrig's layout (column i at azimuth 2 pi (i + 0.5) / W), e.g. written by save_probe.
  kDesignNotes,
};

struct LoadOptions {
  FileAzimuth azimuth = FileAzimuth::kPanorama;
  /// Resample to this width (height width / 2) after loading; 0 keeps the file's size.
  int width = 0;
};

/// Loads an equirectangular OpenEXR light probe with channels R, G, B (any pixel type), row 0 looking up. Files
/// written by save_probe (attribute "vdrig.probe.version") are read in vdrig's layout with their pose and
/// depth whatever options.azimuth says. Errors: kNotFound (missing file), kCorrupt (unreadable EXR, missing R/G/B,
/// non-finite pixels), kInvalidArgument (not 2:1, or options.width odd or < 2 but not 0). Negative values (DWA
/// compression ringing around zero) are clamped to 0 and counted in the log. `file_layout` (optional) receives the
/// layout the file's columns were read in (kDesignNotes for files written by save_probe), for writing a derived map
/// back in the same layout.
Result<Probe> load_probe(const std::filesystem::path& path, const LoadOptions& options = {},
                         FileAzimuth* file_layout = nullptr);

/// Writes the probe as float OpenEXR. In vdrig's layout (the default): channels R, G, B (+ "Z" = depth in mm when
/// present) and attributes vdrig.probe.version = 1, vdrig.probe.layout = "design-notes", position and rotation.
/// With FileAzimuth::kPanorama: the columns mirrored back to the panorama layout (load_probe's inverse), channels
/// R, G, B only and no vdrig attributes, so that the file lies pixel for pixel over the panorama it came from and
/// load_probe with default options reads it back unchanged (the pose is not stored).
Status save_probe(const std::filesystem::path& path, const Probe& probe,
                  FileAzimuth layout = FileAzimuth::kDesignNotes);

/// The probe resampled to `width` x width / 2 (width even, >= 2). Shrinking by an integer factor averages each
/// block weighted by solid angle, which keeps total_power exactly; other shrink factors use OpenCV's box-weighted
/// area averaging; enlarging uses bilinear lookup (radiance_at). Depth is resampled the same way.
Probe resample(const Probe& probe, int width);

/// Radiance in direction `dir` (probe frame, any non-zero length): bilinear between the four nearest pixel centres,
/// wrapping in azimuth and clamping to the first/last row beyond the outermost row centres.
Rgb radiance_at(const Probe& probe, const Vec3d& dir);

/// Total incident "power" of the map: integral of L over the sphere, sum of L(pixel) * solid angle(pixel) (sr * L).
Rgb total_power(const Probe& probe);

/// Sum of solid angles over all pixels (4 pi up to rounding); a self-check of the quadrature.
double total_solid_angle(const Probe& probe);

/// Brightest pixel by luminance: its column, row and direction through the pixel centre.
struct BrightestPixel {
  int column = 0;
  int row = 0;
  Vec3d direction = Vec3d::UnitZ();
  Rgb radiance = Rgb::Zero();
};
BrightestPixel brightest_pixel(const Probe& probe);

/// Brute-force irradiance E(n) = integral of L(w) max(0, n . w) dw, summed over every pixel of the map (at its
/// centre direction, with the pixel's exact solid angle). Built once per map, then O(pixels) per normal.
/// `max_width` > 0 first resamples the map down to that width (resample): E is a cosine-weighted integral, so a
/// smaller map changes it little at a cost proportional to its pixels (docs/probe.md, Rendering, gives the error).
class IrradianceIntegrator {
 public:
  explicit IrradianceIntegrator(const Probe& probe, int max_width = 0);
  /// Over any quadrature of the sphere (a cube map's texels): unit directions and radiance x solid angle, paired.
  IrradianceIntegrator(const std::vector<Vec3d>& directions, const std::vector<Rgb>& radiance_times_sr);
  /// E(n) for a unit normal n in the probe frame.
  Rgb irradiance(const Vec3d& normal) const;
  int width() const { return width_; }

 private:
  int width_ = 0;
  std::vector<float> dirs_;      // 3 per pixel
  std::vector<float> weighted_;  // L * solid angle, 3 per pixel
};

/// `count` unit vectors spread evenly over the sphere (Fibonacci spiral), for tests and benchmarks.
std::vector<Vec3d> fibonacci_directions(int count);

}  // namespace vdrig::probe

// Shading a virtual object with a light probe: a Lambertian sphere rendered orthographically, its irradiance from
// brute-force integration over the map, from median-cut lights, or from the 9-coefficient SH irradiance.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

enum class ShadingMode { kBruteForce, kMedianCut, kSh9 };

/// "brute", "median-cut", "sh".
const char* to_string(ShadingMode mode);
/// Inverse of to_string; false for an unknown name.
bool parse_shading_mode(const std::string& name, ShadingMode* mode);

struct SphereRenderOptions {
  int size_px = 256;                // the image is size_px x size_px, the sphere touching its borders
  Rgb albedo = Rgb::Constant(0.8);  // diffuse reflectance, each channel in [0, 1]
  ShadingMode mode = ShadingMode::kSh9;
  int light_count = 256;            // kMedianCut: number of lights, a power of two
  int brute_width = 256;            // kBruteForce: map width integrated (IrradianceIntegrator's max_width)
  Vec3d view_dir = Vec3d::UnitX();  // probe frame, from the sphere toward the (orthographic) camera
  Vec3d up = Vec3d::UnitZ();        // probe frame, image up (made orthogonal to view_dir)
  int threads = 0;                  // 0: hardware concurrency

  /// False with the reason for a size outside 1..4096, albedo outside [0, 1], a non-power-of-two light count,
  /// an odd or < 2 brute width, or view/up that are zero or parallel.
  bool is_valid(std::string* why = nullptr) const;
};

/// Outgoing radiance of the sphere, albedo / pi * E(n), as CV_32FC3 in B, G, R order; 0 outside the sphere.
/// The pixel (x, y) (row y downward) sees the normal a right + b up + sqrt(1 - a^2 - b^2) view_dir with
/// a = (2 (x + 0.5) / N - 1), b = -(2 (y + 0.5) / N - 1), right = up x view_dir. Precondition: options.is_valid().
cv::Mat render_diffuse_sphere(const Probe& probe, const SphereRenderOptions& options);

/// Display tone mapping (docs/conventions.md), y = 1 - exp(-gamma x) per channel, then sRGB encoding, 8-bit:
/// B, G, R float in, B, G, R CV_8UC3 out (ready for write_png).
cv::Mat tone_map_srgb8(const cv::Mat& bgr, double gamma);

/// A gamma mapping the mean luminance of the image's non-zero pixels to 0.5 (1 if there are none).
double auto_gamma(const cv::Mat& bgr);

/// A display image of the sphere (what `vdrig probe render` and `vdrig probe fuse --render` write as PNG).
struct SphereImage {
  cv::Mat bgr8;      // tone_map_srgb8 of render_diffuse_sphere
  double gamma = 0;  // the tone-mapping gamma used
};

/// render_diffuse_sphere, then tone_map_srgb8 with `gamma`, or with auto_gamma of the render when gamma is 0.
/// Errors (kInvalidArgument, with the reason): invalid options, gamma negative or not finite.
Result<SphereImage> render_sphere_image(const Probe& probe, const SphereRenderOptions& options, double gamma = 0);

}  // namespace vdrig::probe

// A synthetic RTI stack with known ground truth: `lights` 8-bit PNG images of `width` x `height` and their .lp,
// lit from a spiral of directions over the hemisphere (elevation 15..90 deg). Texel (s, t) (image column s, row
// height - 1 - t) has radiance albedo(s, t) * (0.15 + 0.7 max(0, n(s, t) . l)) with a smoothly varying normal and
// colour, stored as codes round(255 radiance) (import with Linearisation::Kind::kCodes, the default).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"

namespace vdrig::test {

struct SyntheticStack {
  std::filesystem::path lp_file;
  std::vector<Vec3d> lights;
  int width = 0, height = 0;

  Vec3d normal(int s, int t) const {
    const double u = 2.0 * s / width - 1.0, v = 2.0 * t / height - 1.0;
    return Vec3d(0.35 * std::sin(2.0 * u), 0.3 * v, 1.0).normalized();
  }
  Vec3d albedo(int s, int t) const {
    return Vec3d(0.9, 0.55 + 0.3 * s / width, 0.35 + 0.4 * t / std::max(1, height - 1));
  }
  /// Ground-truth radiance of texel (s, t) under light direction l (before 8-bit quantisation).
  Vec3d radiance(int s, int t, const Vec3d& l) const {
    return albedo(s, t) * (0.15 + 0.7 * std::max(0.0, normal(s, t).dot(l)));
  }
};

inline std::vector<Vec3d> spiral_lights(int n) {
  std::vector<Vec3d> dirs;
  const double min_z = std::sin(15.0 * std::numbers::pi / 180.0);
  for (int i = 0; i < n; ++i) {
    const double z = min_z + (1.0 - min_z) * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
    const double phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
    dirs.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  return dirs;
}

/// Writes the stack into `folder` (image_000.png ..., stack.lp). `ext` picks the image format (".png", ".jpg").
inline SyntheticStack write_synthetic_stack(const std::filesystem::path& folder, int width, int height, int lights,
                                            const std::string& ext = ".png") {
  SyntheticStack stack;
  stack.width = width;
  stack.height = height;
  stack.lights = spiral_lights(lights);
  stack.lp_file = folder / "stack.lp";
  std::string lp = std::to_string(lights) + "\n";
  for (int v = 0; v < lights; ++v) {
    char name[32];
    std::snprintf(name, sizeof name, "image_%03d%s", v, ext.c_str());
    cv::Mat bgr(height, width, CV_8UC3);
    for (int row = 0; row < height; ++row)
      for (int s = 0; s < width; ++s) {
        const Vec3d rgb = stack.radiance(s, height - 1 - row, stack.lights[static_cast<size_t>(v)]);
        for (int c = 0; c < 3; ++c)
          bgr.at<cv::Vec3b>(row, s)[2 - c] = static_cast<uint8_t>(std::lround(std::clamp(rgb[c], 0.0, 1.0) * 255));
      }
    // OpenCV's imgcodecs writes the stacks: an encoder independent of vdrig's libjpeg and libpng readers.
    cv::imwrite((folder / name).string(), bgr, {cv::IMWRITE_JPEG_QUALITY, 95});
    const Vec3d& l = stack.lights[static_cast<size_t>(v)];
    char line[160];
    std::snprintf(line, sizeof line, "%s %.9f %.9f %.9f\n", name, l.x(), l.y(), l.z());
    lp += line;
  }
  FILE* f = std::fopen(stack.lp_file.c_str(), "w");
  if (!f) {
    std::fprintf(stderr, "cannot write %s\n", stack.lp_file.c_str());
    std::abort();
  }
  std::fputs(lp.c_str(), f);
  std::fclose(f);
  return stack;
}

}  // namespace vdrig::test

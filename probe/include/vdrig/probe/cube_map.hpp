// Cube maps: the environment as six square faces, and conversions to and from the lat-long Probe (docs/probe.md,
// "Cube maps").
//
// Face convention: OpenGL's cube-map table (GL 4.6 spec, table 8.19) applied to the probe frame's axes as they are
// (vdrig's +z is up, so the +Z face looks up). A direction d picks the face of its largest |component| (major axis
// ma; ties go to x before y before z), then
//   face  sc   tc        face  sc   tc
//   +X    -z   -y        -X    +z   -y
//   +Y    +x   +z        -Y    +x   -z
//   +Z    +x   -y        -Z    -x   -y
// s = (sc / |ma| + 1) / 2, t = (tc / |ma| + 1) / 2 in [0, 1]; texel column = s N, row = t N (row 0 is the first
// row of the face's cv::Mat and of the file). Texel (i, j) covers [i, i + 1) x [j, j + 1) of those coordinates.
// Radiance is CV_32FC3 in B, G, R order as Probe's (probe.hpp); texel() and set_texel() convert to and from Rgb.
#pragma once

#include <array>
#include <filesystem>
#include <opencv2/core.hpp>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

enum class CubeFace { kPosX = 0, kNegX, kPosY, kNegY, kPosZ, kNegZ };
inline constexpr int kCubeFaceCount = 6;
/// "+x", "-x", "+y", "-y", "+z", "-z".
const char* to_string(CubeFace face);

/// `CubeMap`: six size x size faces (CV_32FC3, linear radiance, >= 0), indexed by CubeFace, in the probe frame.
struct CubeMap {
  int size = 0;
  std::array<cv::Mat, kCubeFaceCount> faces;

  Rgb texel(CubeFace face, int i, int j) const { return from_bgr(faces[static_cast<int>(face)].at<cv::Vec3f>(j, i)); }
  void set_texel(CubeFace face, int i, int j, const Rgb& c) {
    faces[static_cast<int>(face)].at<cv::Vec3f>(j, i) = to_bgr(c);
  }
};

/// Six black faces of size x size; VDRIG_CHECKs size >= 1.
CubeMap make_cube_map(int size);

/// Continuous texel coordinates of a direction: the face, and (x, y) = (s N, t N) in [0, N] (texel (i, j) covers
/// x in [i, i + 1), y in [j, j + 1)). `dir` any non-zero length.
struct CubeCoordinates {
  CubeFace face = CubeFace::kPosX;
  double x = 0, y = 0;
};
CubeCoordinates cube_coordinates(const Vec3d& dir, int size);

/// Unit direction through the point (x, y) of a face (texel centres at i + 0.5, j + 0.5).
Vec3d cube_direction(CubeFace face, double x, double y, int size);

/// Exact solid angle (sr) of texel (i, j), the same on every face: the spherical area of the square's projection,
/// F(a0, b0) - F(a0, b1) - F(a1, b0) + F(a1, b1) with F(a, b) = atan2(a b, sqrt(a^2 + b^2 + 1)) over the texel's
/// corners a, b in [-1, 1]. The texels of a cube sum to 4 pi up to rounding.
double cube_texel_solid_angle(int i, int j, int size);

/// Sum of every texel's solid angle (4 pi up to rounding), a self-check.
double total_solid_angle(const CubeMap& cube);

/// Integral of L over the sphere (sum of texel radiance x exact solid angle).
Rgb total_power(const CubeMap& cube);

/// The cube as a quadrature of the sphere: each texel's centre direction and radiance x exact solid angle, paired
/// (what project_sh9, IrradianceIntegrator and soft_lights take). Appends to both vectors.
void cube_quadrature(const CubeMap& cube, std::vector<Vec3d>* directions, std::vector<Rgb>* radiance_times_sr);

/// The cube shrunk by an integer `factor` (size a multiple of it): each texel the solid-angle-weighted mean of its
/// factor x factor block, so total_power is kept (to the float rounding of the texels, ~1e-8). VDRIG_CHECKs factor
/// >= 1 dividing size.
CubeMap downsample_cube(const CubeMap& cube, int factor);

/// Radiance in direction `dir`: bilinear between texel centres of the face `dir` falls on, clamped at the face's
/// edges (no filtering across faces).
Rgb radiance_at(const CubeMap& cube, const Vec3d& dir);

/// The lat-long map resampled to a cube of `size`: each texel is the mean of samples x samples bilinear look-ups
/// (radiance_at) spread evenly over it. VDRIG_CHECKs size >= 1, samples >= 1.
CubeMap latlong_to_cube(const Probe& probe, int size, int samples = 2);

/// The cube resampled to a height x 2 height lat-long probe (pose at the origin, no depth), each pixel the mean of
/// samples x samples cube look-ups (radiance_at) spread evenly over it in angle.
Probe cube_to_latlong(const CubeMap& cube, int height, int samples = 2);

/// Writes the cube as float OpenEXR: one 6 N x N image, the faces side by side in CubeFace order (+x, -x, +y, -y,
/// +z, -z), channels R, G, B, attributes vdrig.cube.version = 1 and vdrig.cube.layout = "strip +x -x +y -y +z -z".
Status save_cube_map(const std::filesystem::path& path, const CubeMap& cube);

/// Reads what save_cube_map writes (any 6 N x N EXR with channels R, G, B, faces in that order). Errors: kNotFound,
/// kCorrupt (unreadable, missing channels, a non-finite value, named with its face and
/// texel), kInvalidArgument (width not 6 x height). Negative values are clamped to 0 as load_probe does.
Result<CubeMap> load_cube_map(const std::filesystem::path& path);

}  // namespace vdrig::probe

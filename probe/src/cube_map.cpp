#include "vdrig/probe/cube_map.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "vdrig/core/image_io.hpp"

namespace vdrig::probe {
namespace {

constexpr const char* kVersionAttr = "vdrig.cube.version";
constexpr const char* kLayoutAttr = "vdrig.cube.layout";
constexpr const char* kLayout = "strip +x -x +y -y +z -z";
constexpr int kFileVersion = 1;

// F(a, b) of cube_texel_solid_angle: solid angle of the face rectangle [0, a] x [0, b] at unit distance (signed).
double corner_area(double a, double b) { return std::atan2(a * b, std::sqrt(a * a + b * b + 1.0)); }

}  // namespace

const char* to_string(CubeFace face) {
  static const char* const names[kCubeFaceCount] = {"+x", "-x", "+y", "-y", "+z", "-z"};
  return names[static_cast<int>(face)];
}

CubeMap make_cube_map(int size) {
  VDRIG_CHECK(size >= 1, "a cube map needs faces of at least one texel");
  CubeMap c;
  c.size = size;
  for (cv::Mat& f : c.faces) f = cv::Mat(size, size, CV_32FC3, cv::Scalar::all(0));
  return c;
}

CubeCoordinates cube_coordinates(const Vec3d& d, int size) {
  const double ax = std::abs(d.x()), ay = std::abs(d.y()), az = std::abs(d.z());
  CubeCoordinates c;
  double sc = 0, tc = 0, ma = 0;
  if (ax >= ay && ax >= az) {
    ma = ax;
    c.face = d.x() >= 0 ? CubeFace::kPosX : CubeFace::kNegX;
    sc = d.x() >= 0 ? -d.z() : d.z();
    tc = -d.y();
  } else if (ay >= az) {
    ma = ay;
    c.face = d.y() >= 0 ? CubeFace::kPosY : CubeFace::kNegY;
    sc = d.x();
    tc = d.y() >= 0 ? d.z() : -d.z();
  } else {
    ma = az;
    c.face = d.z() >= 0 ? CubeFace::kPosZ : CubeFace::kNegZ;
    sc = d.z() >= 0 ? d.x() : -d.x();
    tc = -d.y();
  }
  VDRIG_CHECK(ma > 0, "cube_coordinates needs a non-zero direction");
  c.x = std::clamp((sc / ma + 1.0) * 0.5 * size, 0.0, static_cast<double>(size));
  c.y = std::clamp((tc / ma + 1.0) * 0.5 * size, 0.0, static_cast<double>(size));
  return c;
}

Vec3d cube_direction(CubeFace face, double x, double y, int size) {
  const double u = 2.0 * x / size - 1.0, v = 2.0 * y / size - 1.0;
  Vec3d d;
  switch (face) {
    case CubeFace::kPosX:
      d = Vec3d(1, -v, -u);
      break;
    case CubeFace::kNegX:
      d = Vec3d(-1, -v, u);
      break;
    case CubeFace::kPosY:
      d = Vec3d(u, 1, v);
      break;
    case CubeFace::kNegY:
      d = Vec3d(u, -1, -v);
      break;
    case CubeFace::kPosZ:
      d = Vec3d(u, -v, 1);
      break;
    case CubeFace::kNegZ:
      d = Vec3d(-u, -v, -1);
      break;
  }
  return d.normalized();
}

double cube_texel_solid_angle(int i, int j, int size) {
  const double a0 = 2.0 * i / size - 1.0, a1 = 2.0 * (i + 1) / size - 1.0;
  const double b0 = 2.0 * j / size - 1.0, b1 = 2.0 * (j + 1) / size - 1.0;
  return corner_area(a0, b0) - corner_area(a0, b1) - corner_area(a1, b0) + corner_area(a1, b1);
}

double total_solid_angle(const CubeMap& cube) {
  double sum = 0;
  for (int j = 0; j < cube.size; ++j)
    for (int i = 0; i < cube.size; ++i) sum += cube_texel_solid_angle(i, j, cube.size);
  return kCubeFaceCount * sum;
}

Rgb total_power(const CubeMap& cube) {
  Rgb sum = Rgb::Zero();
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < cube.size; ++j)
      for (int i = 0; i < cube.size; ++i)
        sum += cube.texel(static_cast<CubeFace>(f), i, j) * cube_texel_solid_angle(i, j, cube.size);
  return sum;
}

Rgb radiance_at(const CubeMap& cube, const Vec3d& dir) {
  const CubeCoordinates c = cube_coordinates(dir, cube.size);
  const int N = cube.size;
  // Texel centres at integer + 0.5: shift, clamp to the outermost centres, interpolate.
  const double x = std::clamp(c.x - 0.5, 0.0, N - 1.0), y = std::clamp(c.y - 0.5, 0.0, N - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, N - 1), y1 = std::min(y0 + 1, N - 1);
  const double ax = x - x0, ay = y - y0;
  return (1 - ax) * (1 - ay) * cube.texel(c.face, x0, y0) + ax * (1 - ay) * cube.texel(c.face, x1, y0) +
         (1 - ax) * ay * cube.texel(c.face, x0, y1) + ax * ay * cube.texel(c.face, x1, y1);
}

CubeMap latlong_to_cube(const Probe& probe, int size, int samples) {
  VDRIG_CHECK(samples >= 1, "latlong_to_cube needs at least one sample per texel");
  CubeMap cube = make_cube_map(size);
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < size; ++j)
      for (int i = 0; i < size; ++i) {
        Rgb sum = Rgb::Zero();
        for (int sy = 0; sy < samples; ++sy)
          for (int sx = 0; sx < samples; ++sx)
            sum += radiance_at(probe, cube_direction(static_cast<CubeFace>(f), i + (sx + 0.5) / samples,
                                                     j + (sy + 0.5) / samples, size));
        cube.set_texel(static_cast<CubeFace>(f), i, j, sum / (samples * samples));
      }
  return cube;
}

void cube_quadrature(const CubeMap& cube, std::vector<Vec3d>* dirs, std::vector<Rgb>* weighted) {
  const int N = cube.size;
  dirs->reserve(dirs->size() + kCubeFaceCount * N * N);
  weighted->reserve(weighted->size() + kCubeFaceCount * N * N);
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < N; ++j)
      for (int i = 0; i < N; ++i) {
        dirs->push_back(cube_direction(static_cast<CubeFace>(f), i + 0.5, j + 0.5, N));
        weighted->push_back(cube.texel(static_cast<CubeFace>(f), i, j) * cube_texel_solid_angle(i, j, N));
      }
}

CubeMap downsample_cube(const CubeMap& cube, int factor) {
  VDRIG_CHECK(factor >= 1 && cube.size % factor == 0, "downsample_cube needs a factor dividing the face size");
  const int N = cube.size, M = N / factor;
  std::vector<double> sa(static_cast<size_t>(N) * N);
  for (int j = 0; j < N; ++j)
    for (int i = 0; i < N; ++i) sa[static_cast<size_t>(j) * N + i] = cube_texel_solid_angle(i, j, N);
  CubeMap out = make_cube_map(M);
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < M; ++j)
      for (int i = 0; i < M; ++i) {
        Rgb sum = Rgb::Zero();
        double w = 0;
        for (int b = 0; b < factor; ++b)
          for (int a = 0; a < factor; ++a) {
            const int x = i * factor + a, y = j * factor + b;
            const double s = sa[static_cast<size_t>(y) * N + x];
            sum += s * cube.texel(static_cast<CubeFace>(f), x, y);
            w += s;
          }
        out.set_texel(static_cast<CubeFace>(f), i, j, sum / w);
      }
  return out;
}

Probe cube_to_latlong(const CubeMap& cube, int height, int samples) {
  VDRIG_CHECK(samples >= 1, "cube_to_latlong needs at least one sample per pixel");
  Probe p = make_probe(height);
  const int W = p.width(), H = p.height();
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      Rgb sum = Rgb::Zero();
      for (int sy = 0; sy < samples; ++sy)
        for (int sx = 0; sx < samples; ++sx)
          sum += radiance_at(cube,
                             latlong_direction(i - 0.5 + (sx + 0.5) / samples, j - 0.5 + (sy + 0.5) / samples, W, H));
      p.set_pixel(i, j, sum / (samples * samples));
    }
  return p;
}

Status save_cube_map(const std::filesystem::path& path, const CubeMap& cube) {
  const int N = cube.size;
  cv::Mat strip(N, kCubeFaceCount * N, CV_32FC3);
  for (int f = 0; f < kCubeFaceCount; ++f) cube.faces[f].copyTo(strip(cv::Rect(f * N, 0, N, N)));
  ExrImage im;
  im.add_bgr(strip);
  im.number_attributes[kVersionAttr] = kFileVersion;
  im.string_attributes[kLayoutAttr] = kLayout;
  return write_exr(path, im);
}

Result<CubeMap> load_cube_map(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path))
    return make_error(ErrorCode::kNotFound, "cube map " + path.string() + " does not exist");
  auto exr = read_exr(path);
  if (!exr) return make_error(exr.error().code, "cube map: " + exr.error().message);
  const ExrImage& im = exr.value();
  const int ch[3] = {im.find("B"), im.find("G"), im.find("R")};  // the faces' order
  if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0)
    return make_error(ErrorCode::kCorrupt, "cube map " + path.string() + " has no R, G and B channels");
  const int N = im.height;
  if (N < 1 || im.width != kCubeFaceCount * N)
    return make_error(ErrorCode::kInvalidArgument,
                      "cube map " + path.string() +
                          " is not a strip of six square faces (width must be 6 x height), got " +
                          std::to_string(im.width) + " x " + std::to_string(im.height));
  CubeMap cube = make_cube_map(N);
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < N; ++j)
      for (int i = 0; i < N; ++i)
        for (int k = 0; k < 3; ++k) {
          const float v = im.channels[ch[k]].at<float>(j, f * N + i);
          if (!std::isfinite(v))
            return make_error(ErrorCode::kCorrupt, "cube map " + path.string() + " has a non-finite value on face " +
                                                       to_string(static_cast<CubeFace>(f)) + " at texel (" +
                                                       std::to_string(i) + ", " + std::to_string(j) + ")");
          cube.faces[f].at<cv::Vec3f>(j, i)[k] = std::max(v, 0.0f);
        }
  return cube;
}

}  // namespace vdrig::probe

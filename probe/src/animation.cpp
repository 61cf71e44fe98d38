#include "vdrig/probe/animation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <thread>

#include "vdrig/probe/cap_lights.hpp"

namespace vdrig::probe {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Basis {
  Vec3d forward, right, up;
};

Basis camera_basis(const SceneCamera& c) {
  Basis b;
  b.forward = (c.look_at_mm - c.position_mm).normalized();
  b.right = b.forward.cross(Vec3d::UnitZ()).normalized();
  b.up = b.right.cross(b.forward);
  return b;
}

// Nearest t > 0 of origin + t dir (dir unit) on the sphere, or infinity.
double hit_sphere(const Vec3d& origin, const Vec3d& dir, const Vec3d& centre, double radius) {
  const Vec3d oc = origin - centre;
  const double b = oc.dot(dir), c = oc.squaredNorm() - radius * radius;
  const double disc = b * b - c;
  if (disc < 0) return kInf;
  const double s = std::sqrt(disc);
  if (-b - s > 1e-6) return -b - s;
  if (-b + s > 1e-6) return -b + s;
  return kInf;
}

// One light's orthographic shadow map over both spheres (see animation.hpp).
struct ShadowMap {
  Vec3d dir, u, v, centre;  // toward the light; the map's axes; the square's centre
  double half_extent = 0, far = 0, texel = 0;
  int size = 0;
  std::vector<double> depth;  // distance along -dir from the plane centre + far * dir; infinity: nothing

  double lookup(int i, int j) const {
    if (i < 0 || j < 0 || i >= size || j >= size) return kInf;
    return depth[static_cast<size_t>(j) * size + i];
  }
  // Fraction of the 3 x 3 texels around x that see the light.
  double visibility(const Vec3d& x) const {
    const Vec3d q = x - centre;
    const double d = far - q.dot(dir);
    const double fi = (q.dot(u) + half_extent) / texel - 0.5, fj = (q.dot(v) + half_extent) / texel - 0.5;
    const int i0 = static_cast<int>(std::lround(fi)), j0 = static_cast<int>(std::lround(fj));
    int lit = 0;
    for (int b = -1; b <= 1; ++b)
      for (int a = -1; a <= 1; ++a)
        if (d <= lookup(i0 + a, j0 + b) + texel) ++lit;
    return lit / 9.0;
  }
};

ShadowMap make_shadow_map(const Vec3d& dir, const std::vector<Vec3d>& centres, double radius, int size) {
  ShadowMap m;
  m.dir = dir.normalized();
  m.u = (std::abs(m.dir.z()) < 0.9 ? m.dir.cross(Vec3d::UnitZ()) : m.dir.cross(Vec3d::UnitX())).normalized();
  m.v = m.dir.cross(m.u);
  m.centre = Vec3d::Zero();
  for (const Vec3d& c : centres) m.centre += c / static_cast<double>(centres.size());
  double spread = 0;
  for (const Vec3d& c : centres) spread = std::max(spread, (c - m.centre).norm());
  m.half_extent = (spread + radius) * 1.05;
  m.far = spread + 2 * radius;
  m.size = size;
  m.texel = 2 * m.half_extent / size;
  m.depth.assign(static_cast<size_t>(size) * size, kInf);
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i) {
      const Vec3d origin = m.centre + m.far * m.dir + ((i + 0.5) * m.texel - m.half_extent) * m.u +
                           ((j + 0.5) * m.texel - m.half_extent) * m.v;
      double t = kInf;
      for (const Vec3d& c : centres) t = std::min(t, hit_sphere(origin, -m.dir, c, radius));
      m.depth[static_cast<size_t>(j) * size + i] = t;
    }
  return m;
}

}  // namespace

bool SceneCamera::is_valid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (width < 1 || height < 1) return fail("camera image size must be positive");
  if (!(fov_deg > 1 && fov_deg < 170)) return fail("camera field of view must lie in (1, 170) degrees");
  if (!position_mm.allFinite() || !look_at_mm.allFinite()) return fail("camera position and look-at must be finite");
  const Vec3d f = look_at_mm - position_mm;
  if (!(f.norm() > 1e-6)) return fail("camera look-at must differ from its position");
  if (f.normalized().cross(Vec3d::UnitZ()).norm() < 1e-3) return fail("camera must not look straight along z");
  return true;
}

double SceneCamera::focal_px() const { return 0.5 * width / std::tan(0.5 * deg_to_rad(fov_deg)); }

Vec3d SceneCamera::ray(double x, double y) const {
  const Basis b = camera_basis(*this);
  return (focal_px() * b.forward + (x - 0.5 * (width - 1)) * b.right - (y - 0.5 * (height - 1)) * b.up).normalized();
}

bool SceneCamera::project(const Vec3d& p, double* x, double* y) const {
  const Basis b = camera_basis(*this);
  const Vec3d q = p - position_mm;
  const double z = q.dot(b.forward);
  if (!(z > 0)) return false;
  *x = 0.5 * (width - 1) + focal_px() * q.dot(b.right) / z;
  *y = 0.5 * (height - 1) - focal_px() * q.dot(b.up) / z;
  return true;
}

bool AnimationScene::is_valid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(sphere_radius_mm > 0)) return fail("sphere radius must be > 0 mm");
  if (shadow_lights < 0) return fail("shadow lights must be >= 0");
  if (shadow_map_size < 8 || shadow_map_size > 4096) return fail("shadow map size must be in [8, 4096]");
  if (samples_per_axis < 1 || samples_per_axis > 8) return fail("samples per axis must be in [1, 8]");
  if (!(glossy_specular >= 0 && glossy_specular <= 1)) return fail("glossy specular weight must be in [0, 1]");
  return true;
}

std::vector<int> strongest_lights(const std::vector<DirectionalLight>& lights, int count) {
  std::vector<int> idx(lights.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::stable_sort(idx.begin(), idx.end(),
                   [&](int a, int b) { return luminance(lights[a].power) > luminance(lights[b].power); });
  idx.resize(std::min<size_t>(idx.size(), static_cast<size_t>(std::max(0, count))));
  return idx;
}

cv::Mat render_animation_frame(const SceneCamera& camera, const AnimationScene& scene, const Vec3d& diffuse_centre,
                               const Vec3d& glossy_centre, const FrameLighting& lighting) {
  std::string why;
  VDRIG_CHECK(camera.is_valid(&why), why);
  VDRIG_CHECK(scene.is_valid(&why), why);
  const double r = scene.sphere_radius_mm;
  const std::vector<Vec3d> centres = {diffuse_centre, glossy_centre};
  const std::vector<DirectionalLight>& lights = lighting.soft.lights;
  std::vector<int> shadowing;
  std::vector<ShadowMap> maps;
  for (int k : strongest_lights(lights, scene.shadow_lights)) {
    if (!(lights[k].direction.z() > 1e-3)) continue;  // below the horizon: the ground does not see it anyway
    shadowing.push_back(k);
    maps.push_back(make_shadow_map(lights[k].direction, centres, r, scene.shadow_map_size));
  }
  const Rgb ground_unshadowed = lighting.soft.irradiance(Vec3d::UnitZ());
  const bool have_env = lighting.environment.size > 0;

  auto shade = [&](const Vec3d& origin, const Vec3d& dir) -> Rgb {
    const double t0 = hit_sphere(origin, dir, diffuse_centre, r), t1 = hit_sphere(origin, dir, glossy_centre, r);
    double tg = kInf;
    if (std::abs(dir.z()) > 1e-12) {
      const double t = (scene.ground_z_mm - origin.z()) / dir.z();
      const Vec3d x = origin + t * dir;
      if (t > 0 && x.x() >= scene.ground_min_mm.x() && x.x() <= scene.ground_max_mm.x() &&
          x.y() >= scene.ground_min_mm.y() && x.y() <= scene.ground_max_mm.y())
        tg = t;
    }
    const double t = std::min({t0, t1, tg});
    if (t == kInf) return Rgb::Zero();
    const Vec3d x = origin + t * dir;
    if (t == t0) {
      const Vec3d n = (x - diffuse_centre).normalized();
      return scene.diffuse_albedo.cwiseProduct(lighting.soft.irradiance(n).cwiseMax(0.0)) / kPi;
    }
    if (t == t1) {
      const Vec3d n = (x - glossy_centre).normalized();
      Rgb c = scene.glossy_albedo.cwiseProduct(lighting.soft.irradiance(n).cwiseMax(0.0)) / kPi;
      if (have_env) c += scene.glossy_specular * radiance_at(lighting.environment, dir - 2 * dir.dot(n) * n);
      return c;
    }
    Rgb e = ground_unshadowed;
    for (size_t s = 0; s < maps.size(); ++s) {
      const double v = maps[s].visibility(x);
      // The light's whole contribution to the ground, its SH-9 share included: its power through its cap.
      const DirectionalLight& l = lights[shadowing[s]];
      if (v < 1) e -= (1 - v) * l.power * cap_clamped_cosine(l.direction.z(), l.cap_cos_half_angle);
    }
    return scene.ground_albedo.cwiseProduct(e.cwiseMax(0.0)) / kPi;
  };

  cv::Mat out(camera.height, camera.width, CV_32FC3);
  const int S = scene.samples_per_axis;
  // Everything shade() reads is built above and read-only here, so bands of rows run in parallel (as shading.cpp).
  auto rows = [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < camera.width; ++x) {
        Rgb sum = Rgb::Zero();
        for (int b = 0; b < S; ++b)
          for (int a = 0; a < S; ++a)
            sum += shade(camera.position_mm, camera.ray(x - 0.5 + (a + 0.5) / S, y - 0.5 + (b + 0.5) / S));
        out.at<cv::Vec3f>(y, x) = to_bgr(sum / (S * S));
      }
  };
  const int threads = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, camera.height);
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back(rows, camera.height * t / threads, camera.height * (t + 1) / threads);
  for (std::thread& t : pool) t.join();
  return out;
}

SceneCamera frame_path(const std::vector<Vec3d>& positions_mm, double sphere_radius_mm, double fov_deg) {
  VDRIG_CHECK(!positions_mm.empty(), "frame_path needs at least one position");
  Vec3d lo = positions_mm[0], hi = positions_mm[0];
  for (const Vec3d& p : positions_mm) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  SceneCamera c;
  c.look_at_mm = Vec3d(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), 0.25 * (lo.z() + hi.z()));
  const double half = 0.5 * std::max(hi.x() - lo.x(), hi.y() - lo.y()) + 3 * sphere_radius_mm;
  const double distance = 1.1 * half / std::tan(0.5 * deg_to_rad(fov_deg));
  const double elevation = deg_to_rad(35);
  c.position_mm = c.look_at_mm + distance * Vec3d(0, -std::cos(elevation), std::sin(elevation));
  c.fov_deg = fov_deg;
  return c;
}

}  // namespace vdrig::probe

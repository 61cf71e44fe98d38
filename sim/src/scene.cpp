#include "vdrig/sim/scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <opencv2/core.hpp>

#include "builtin_scenes.hpp"
#include "vdrig/sim/ggx.hpp"
#include "vdrig/sim/scene_file.hpp"

namespace vdrig::sim {
namespace {

// Bump pattern: h(x, y) = sum_k w_k sin(2 pi (a_k x + b_k y) / P + phase_k) * P / (2 pi); incommensurate
// directions so it does not look like one grating. Its gradient is sum_k w_k (a_k, b_k) cos(...).
struct BumpWave {
  double a, b, w, phase;
};
constexpr BumpWave kBumpWaves[] = {
    {1.0, 0.31, 0.45, 0.3},
    {-0.27, 1.13, 0.35, 1.7},
    {0.71, -0.77, 0.20, 4.1},
};

Vec3d bump_normal(const Material& m, double x, double y) {
  const double k = 2.0 * kPi / m.bump_period_mm;
  double hx = 0, hy = 0;
  for (const auto& w : kBumpWaves) {
    const double c = w.w * std::cos(k * (w.a * x + w.b * y) + w.phase);
    hx += w.a * c;
    hy += w.b * c;
  }
  return Vec3d(-m.bump_slope * hx, -m.bump_slope * hy, 1.0).normalized();
}

uint32_t hash3(int32_t a, int32_t b, int32_t c) {
  uint32_t h = static_cast<uint32_t>(a) * 0x8da6b343u ^ static_cast<uint32_t>(b) * 0xd8163841u ^
               static_cast<uint32_t>(c) * 0xcb1ab31fu;
  h ^= h >> 15;
  h *= 0x2c1b3c6du;
  h ^= h >> 12;
  h *= 0x297a2d39u;
  h ^= h >> 15;
  return h;
}

// Text-like print: glyphs of 3 x 5 cells (some are spaces), advance 4 cells, line pitch 8 cells.
bool has_ink(const Material& m, double x, double y) {
  const double u = m.print_cell_mm;
  const auto cx = static_cast<int32_t>(std::floor(x / u)), cy = static_cast<int32_t>(std::floor(-y / u));
  const int32_t col = cx >= 0 ? cx / 4 : (cx - 3) / 4, row = cy >= 0 ? cy / 8 : (cy - 7) / 8;
  const int gx = cx - col * 4, gy = cy - row * 8;
  if (gx >= 3 || gy >= 5) return false;
  if (hash3(col, row, 99) % 6 == 0) return false;   // word spaces
  return (hash3(col, row, gx * 5 + gy) & 3u) < 2u;  // about half the cells of a glyph are inked
}

Vec3d apply_light(const SurfacePoint& sp, const Material& mat, const Vec3d& p, const Vec3d& v, const Vec3d& light_pos,
                  const Vec3d& intensity, bool specular) {
  const Vec3d to_light = light_pos - p;
  const double d2 = to_light.squaredNorm();
  const Vec3d l = to_light / std::sqrt(d2);
  const double cos_i = l.dot(sp.normal);
  if (cos_i <= 0.0) return Vec3d::Zero();
  const Vec3d E = intensity * (cos_i / d2);
  if (!specular) return E.cwiseProduct(sp.kd);
  if (mat.kind == MaterialKind::kGgx) {
    const Mat3d frame = ggx_local_frame(sp.normal);
    const double ay = mat.roughness_y > 0.0 ? mat.roughness_y : mat.roughness;
    const Vec3d f = ggx_brdf(frame * l, frame * v, mat.roughness, ay, mat.f0);
    return E.cwiseProduct(sp.kd + kPi * f);
  }
  const double rv = mirror_direction(l, sp.normal).dot(v);
  const double spec = rv > 0.0 ? std::pow(rv, mat.shininess) : 0.0;
  return E.cwiseProduct(sp.kd + mat.ks * spec);
}

// The rectangle [x0, x1] x [y0, y1] a material's image is stretched over at (x, y): the disc's bounding square, the
// patch's rectangle or the whole surface (in the order material_at() decides the material).
std::array<double, 4> texture_rect(const Scene& s, int material, double x, double y) {
  for (const Disc& d : s.markers)
    if ((Vec2d(x, y) - d.centre_mm).squaredNorm() <= d.radius_mm * d.radius_mm)
      return {d.centre_mm.x() - d.radius_mm, d.centre_mm.y() - d.radius_mm, d.centre_mm.x() + d.radius_mm,
              d.centre_mm.y() + d.radius_mm};
  for (auto it = s.patches.rbegin(); it != s.patches.rend(); ++it)
    if (x >= it->x0_mm && x <= it->x1_mm && y >= it->y0_mm && y <= it->y1_mm && it->material == material)
      return {it->x0_mm, it->y0_mm, it->x1_mm, it->y1_mm};
  return {-s.width_mm / 2, -s.height_mm / 2, s.width_mm / 2, s.height_mm / 2};
}

// Bilinear sample (pixel centres at half-pixel offsets, clamped at the border) of an RGB CV_32FC3 image stretched
// over rect.
Vec3d texture_kd(const cv::Mat& image, const std::array<double, 4>& rect, double x, double y) {
  const double px = (x - rect[0]) / (rect[2] - rect[0]) * image.cols - 0.5;
  const double py = (y - rect[1]) / (rect[3] - rect[1]) * image.rows - 0.5;
  const double fx = std::clamp(px, 0.0, image.cols - 1.0), fy = std::clamp(py, 0.0, image.rows - 1.0);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const double ax = fx - x0, ay = fy - y0;
  auto at = [&](int c, int r) {
    const cv::Vec3f& v = image.at<cv::Vec3f>(r, c);
    return Vec3d(v[0], v[1], v[2]);
  };
  return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x1, y0)) + ay * ((1 - ax) * at(x0, y1) + ax * at(x1, y1));
}

}  // namespace

int Scene::material_at(double x, double y) const {
  if (std::abs(x) > width_mm / 2.0 || std::abs(y) > height_mm / 2.0) return -1;
  for (const Disc& d : markers)
    if ((Vec2d(x, y) - d.centre_mm).squaredNorm() <= d.radius_mm * d.radius_mm) return d.material;
  for (auto it = patches.rbegin(); it != patches.rend(); ++it)
    if (x >= it->x0_mm && x <= it->x1_mm && y >= it->y0_mm && y <= it->y1_mm) return it->material;
  return 0;
}

SurfacePoint Scene::surface_at(double x, double y) const {
  SurfacePoint sp;
  sp.material = material_at(x, y);
  if (sp.material < 0) return sp;
  const Material& m = materials[sp.material];
  if (m.bump_slope > 0.0) sp.normal = bump_normal(m, x, y);
  sp.kd = m.kd_texture ? texture_kd(*m.kd_texture, texture_rect(*this, sp.material, x, y), x, y) : m.kd;
  if (m.printed && has_ink(m, x, y)) sp.kd = m.ink_kd;
  return sp;
}

Vec3d Scene::radiance(const Vec3d& p, const Vec3d& v) const {
  if (v.z() <= 0.0) return Vec3d::Zero();
  const SurfacePoint sp = surface_at(p.x(), p.y());
  if (sp.material < 0) return Vec3d::Zero();
  const Material& mat = materials[sp.material];
  const bool specular = mat.kind == MaterialKind::kGgx || !mat.ks.isZero();  // Lambertian materials skip pow
  Vec3d L = sp.kd.cwiseProduct(ambient);
  for (const PointLight& light : lights) L += apply_light(sp, mat, p, v, light.position_mm, light.intensity, specular);
  for (const AreaLight& a : area_lights) {
    const int n = a.samples_per_axis;
    const Vec3d nl = a.normal();
    const Vec3d per_sample = a.intensity / (n * n);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Vec3d q = a.centre_mm + ((i + 0.5) / n - 0.5) * a.edge_u_mm + ((j + 0.5) / n - 0.5) * a.edge_v_mm;
        const double cos_emit = (p - q).normalized().dot(nl);
        if (cos_emit <= 0.0) continue;
        L += apply_light(sp, mat, p, v, q, per_sample * cos_emit, specular);
      }
  }
  return L;
}

std::optional<PhongTruth> Scene::phong_truth(const Vec3d& p) const {
  if (lights.size() != 1 || !area_lights.empty() || !ambient.isZero()) return std::nullopt;
  const SurfacePoint sp = surface_at(p.x(), p.y());
  if (sp.material < 0) return std::nullopt;
  const Material& mat = materials[sp.material];
  if (mat.kind != MaterialKind::kPhong) return std::nullopt;
  const Vec3d to_light = lights[0].position_mm - p;
  const double d2 = to_light.squaredNorm();
  const Vec3d l = to_light / std::sqrt(d2);
  const double cos_i = l.dot(sp.normal);
  if (cos_i <= 0.0) return std::nullopt;
  const Vec3d E = lights[0].intensity * (cos_i / d2);
  return PhongTruth{E.cwiseProduct(sp.kd), E.cwiseProduct(mat.ks), mirror_direction(l, sp.normal), mat.shininess};
}

std::vector<Vec3d> Scene::marker_centres_mm() const {
  std::vector<Vec3d> out;
  for (const Disc& d : markers) out.emplace_back(d.centre_mm.x(), d.centre_mm.y(), 0.0);
  return out;
}

bool Scene::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = "scene " + name + ": " + m;
    return false;
  };
  if (!(width_mm > 0) || !(height_mm > 0)) return fail("surface size must be positive");
  if (materials.empty()) return fail("needs at least a background material");
  for (const auto& m : materials) {
    if (m.kind == MaterialKind::kGgx &&
        (!(m.roughness > 0) || m.roughness_y < 0 || (m.f0.array() < 0).any() || (m.f0.array() > 1).any()))
      return fail("material " + m.name + " needs roughness > 0, roughness_y >= 0 and f0 in [0, 1]");
    if (m.shininess < 1.0 || (m.kd.array() < 0).any() || (m.ks.array() < 0).any())
      return fail("material " + m.name + " needs kd, ks >= 0 and shininess >= 1");
    if (m.bump_slope < 0 || !(m.bump_period_mm > 0) || !(m.print_cell_mm > 0))
      return fail("material " + m.name + " needs bump_slope >= 0 and positive bump period and print cell");
  }
  const auto n_mat = static_cast<int>(materials.size());
  for (const auto& p : patches)
    if (p.material < 0 || p.material >= n_mat) return fail("patch material out of range");
  for (const auto& d : markers)
    if (d.material < 0 || d.material >= n_mat || !(d.radius_mm > 0)) return fail("marker needs a material, radius > 0");
  for (const auto& a : area_lights)
    if (a.samples_per_axis < 1 || !(a.edge_u_mm.cross(a.edge_v_mm).norm() > 0))
      return fail("area light needs samples_per_axis >= 1 and non-parallel edges");
  return true;
}

double band_shininess(int k) { return 2.0 * std::pow(250.0, k / 7.0); }

std::vector<std::string> scene_names() {
  std::vector<std::string> names;
  for (const auto& file : builtin_scene_files()) names.emplace_back(file.name);
  return names;
}

Result<Scene> make_scene(const std::string& name) {
  if (name.size() > 5 && name.ends_with(".json")) return load_scene_file(name);
  for (const auto& file : builtin_scene_files())
    if (name == file.name) {
      auto scene = parse_scene(nlohmann::json::parse(file.json), "built-in scene " + name);
      VDRIG_CHECK(scene.is_ok(), "built-in scene files are valid: " + scene.error().message);
      return scene;
    }
  std::string known;
  for (const auto& n : scene_names()) known += (known.empty() ? "" : ", ") + n;
  return make_error(ErrorCode::kInvalidArgument,
                    "unknown scene \"" + name + "\"; known: " + known + " (or a scene file NAME.json)");
}

}  // namespace vdrig::sim

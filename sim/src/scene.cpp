#include "vdrig/sim/scene.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>

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
  const double rv = mirror_direction(l, sp.normal).dot(v);
  const double spec = rv > 0.0 ? std::pow(rv, mat.shininess) : 0.0;
  return E.cwiseProduct(sp.kd + mat.ks * spec);
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
  sp.kd = m.printed && has_ink(m, x, y) ? m.ink_kd : m.kd;
  return sp;
}

Vec3d Scene::radiance(const Vec3d& p, const Vec3d& v) const {
  if (v.z() <= 0.0) return Vec3d::Zero();
  const SurfacePoint sp = surface_at(p.x(), p.y());
  if (sp.material < 0) return Vec3d::Zero();
  const Material& mat = materials[sp.material];
  const bool specular = !mat.ks.isZero();  // Lambertian materials skip pow
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

namespace {

// The light of the source method's test setup: a white point light at (1500, 1500, 2000) mm. Its intensity is
// chosen so the irradiance at the surface centre is 1 (d^2 = 8.5e6 mm^2, cos = 0.686).
PointLight standard_light() {
  const Vec3d pos(1500, 1500, 2000);
  const double d2 = pos.squaredNorm();
  return {pos, Vec3d::Constant(d2 / (pos.z() / std::sqrt(d2)))};
}

// Four black discs, 30 mm radius, centred 50 mm in from each corner; order (-,-), (+,-), (+,+), (-,+).
void add_corner_markers(Scene& s) {
  s.materials.push_back({"marker black", Vec3d::Constant(0.02), Vec3d::Zero(), 1.0});
  const int m = static_cast<int>(s.materials.size()) - 1;
  const double x = s.width_mm / 2 - 50, y = s.height_mm / 2 - 50;
  s.markers = {{{-x, -y}, 30.0, m}, {{x, -y}, 30.0, m}, {{x, y}, 30.0, m}, {{-x, y}, 30.0, m}};
}

// Eight bands of one colour, shininess m = 2 .. 500, over [x0, x1] x [y0, y1].
void add_bands(Scene& s, double x0, double y0, double x1, double y1) {
  const double w = (x1 - x0) / 8.0;
  for (int k = 0; k < 8; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "band m=%.0f", band_shininess(k));
    s.materials.push_back({name, {0.25, 0.30, 0.35}, {0.45, 0.45, 0.45}, band_shininess(k)});
    s.patches.push_back({x0 + k * w, y0, x0 + (k + 1) * w, y1, static_cast<int>(s.materials.size()) - 1});
  }
}

Scene patchwork() {
  Scene s;
  s.name = "patchwork";
  // Indices 0..2 are relied on by callers (the demo takes the first Lambertian patch, red cloth, as its region).
  s.materials = {
      {"paper", {0.70, 0.68, 0.62}, {0.02, 0.02, 0.02}, 4.0},
      {"red cloth", {0.60, 0.08, 0.06}, {0, 0, 0}, 1.0},
      {"glossy plastic", {0.10, 0.20, 0.45}, {0.50, 0.50, 0.50}, 60.0},
  };
  Material metal{"brushed metal", {0.04, 0.035, 0.03}, {0.75, 0.62, 0.45}, 150.0};
  metal.bump_slope = 0.08;
  metal.bump_period_mm = 6.0;
  Material print{"printed paper", {0.80, 0.78, 0.72}, {0.03, 0.03, 0.03}, 8.0};
  print.printed = true;
  print.ink_kd = {0.05, 0.05, 0.07};
  s.materials.push_back(metal);
  s.materials.push_back(print);
  // Red diffuse patch in the -x,-y quadrant; glossy patch in the +x,-y quadrant; metal and print above them; the
  // shininess band near the top; paper elsewhere (and around the corner markers).
  s.patches = {{-400, -400, -50, -50, 1}, {50, -400, 400, -50, 2}, {-400, 50, -50, 250, 3}, {50, 50, 400, 250, 4}};
  add_bands(s, -400, 290, 400, 400);
  add_corner_markers(s);
  s.lights = {standard_light()};
  return s;
}

Scene bands() {
  Scene s;
  s.name = "bands";
  s.materials = {{"paper", {0.70, 0.68, 0.62}, {0.02, 0.02, 0.02}, 4.0}};
  add_bands(s, -400, -400, 400, 400);
  add_corner_markers(s);
  s.lights = {standard_light()};
  return s;
}

Scene lights2() {
  Scene s = patchwork();
  s.name = "lights2";
  s.lights.push_back({Vec3d(-1500, 1000, 2000), s.lights[0].intensity * 0.4});
  return s;
}

Scene softbox() {
  Scene s = patchwork();
  s.name = "softbox";
  const PointLight p = standard_light();
  // A 400 x 400 mm panel at the point light's place, facing the surface centre.
  const Vec3d nrm = (-p.position_mm).normalized();
  const Vec3d u = Vec3d::UnitZ().cross(nrm).normalized() * 400.0;
  const Vec3d v = nrm.cross(u).normalized() * 400.0;  // u x v = 400^2 nrm: emits toward the surface
  s.lights.clear();
  s.area_lights = {{p.position_mm, u, v, p.intensity, 6}};
  s.ambient = Vec3d::Constant(0.05);
  return s;
}

}  // namespace

std::vector<std::string> scene_names() { return {"patchwork", "bands", "lights2", "softbox"}; }

Result<Scene> make_scene(const std::string& name) {
  if (name == "patchwork") return patchwork();
  if (name == "bands") return bands();
  if (name == "lights2") return lights2();
  if (name == "softbox") return softbox();
  std::string known;
  for (const auto& n : scene_names()) known += (known.empty() ? "" : ", ") + n;
  return make_error(ErrorCode::kInvalidArgument, "unknown scene \"" + name + "\"; known: " + known);
}

}  // namespace vdrig::sim

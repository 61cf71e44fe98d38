#include "vdrig/sim/scene.hpp"

#include <cmath>

namespace vdrig::sim {

int Scene::material_at(double x, double y) const {
  if (std::abs(x) > width_mm / 2.0 || std::abs(y) > height_mm / 2.0) return -1;
  for (auto it = patches.rbegin(); it != patches.rend(); ++it)
    if (x >= it->x0_mm && x <= it->x1_mm && y >= it->y0_mm && y <= it->y1_mm) return it->material;
  return 0;
}

Vec3d Scene::radiance(const Vec3d& p, const Vec3d& v) const {
  const int mi = material_at(p.x(), p.y());
  if (mi < 0 || v.z() <= 0.0) return Vec3d::Zero();
  const Material& mat = materials[mi];
  const Vec3d n = Vec3d::UnitZ();
  Vec3d L = mat.kd.cwiseProduct(ambient);
  for (const PointLight& light : lights) {
    const Vec3d to_light = light.position_mm - p;
    const double d2 = to_light.squaredNorm();
    const Vec3d l = to_light / std::sqrt(d2);
    const double cos_i = l.dot(n);
    if (cos_i <= 0.0) continue;
    const Vec3d E = light.intensity * (cos_i / d2);
    const double rv = mirror_direction(l, n).dot(v);
    const double spec = rv > 0.0 ? std::pow(rv, mat.shininess) : 0.0;
    L += E.cwiseProduct(mat.kd + mat.ks * spec);
  }
  return L;
}

std::optional<PhongTruth> Scene::phong_truth(const Vec3d& p) const {
  const int mi = material_at(p.x(), p.y());
  if (mi < 0 || lights.size() != 1 || !ambient.isZero()) return std::nullopt;
  const Material& mat = materials[mi];
  const Vec3d to_light = lights[0].position_mm - p;
  const double d2 = to_light.squaredNorm();
  const Vec3d l = to_light / std::sqrt(d2);
  const double cos_i = l.z();
  if (cos_i <= 0.0) return std::nullopt;
  const Vec3d E = lights[0].intensity * (cos_i / d2);
  return PhongTruth{E.cwiseProduct(mat.kd), E.cwiseProduct(mat.ks), mirror_direction(l, Vec3d::UnitZ()),
                    mat.shininess};
}

bool Scene::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = "scene " + name + ": " + m;
    return false;
  };
  if (!(width_mm > 0) || !(height_mm > 0)) return fail("surface size must be positive");
  if (materials.empty()) return fail("needs at least a background material");
  for (const auto& m : materials)
    if (m.shininess < 1.0 || (m.kd.array() < 0).any() || (m.ks.array() < 0).any())
      return fail("material " + m.name + " needs kd, ks >= 0 and shininess >= 1");
  for (const auto& p : patches)
    if (p.material < 0 || p.material >= static_cast<int>(materials.size())) return fail("patch material out of range");
  return true;
}

namespace {

// The light of the source method's test setup: a white point light at (1500, 1500, 2000) mm. Its intensity is
// chosen so the irradiance at the surface centre is 1 (d^2 = 8.5e6 mm^2, cos = 0.686).
PointLight standard_light() {
  const Vec3d pos(1500, 1500, 2000);
  const double d2 = pos.squaredNorm();
  return {pos, Vec3d::Constant(d2 / (pos.z() / std::sqrt(d2)))};
}

Scene patchwork() {
  Scene s;
  s.name = "patchwork";
  s.materials = {
      {"paper", {0.70, 0.68, 0.62}, {0.02, 0.02, 0.02}, 4.0},
      {"red cloth", {0.60, 0.08, 0.06}, {0, 0, 0}, 1.0},
      {"glossy plastic", {0.10, 0.20, 0.45}, {0.50, 0.50, 0.50}, 60.0},
  };
  // Red diffuse patch in the -x,-y quadrant; glossy patch in the +x,-y quadrant; paper elsewhere.
  s.patches = {{-400, -400, -50, -50, 1}, {50, -400, 400, -50, 2}};
  s.lights = {standard_light()};
  return s;
}

}  // namespace

std::vector<std::string> scene_names() { return {"patchwork"}; }

Result<Scene> make_scene(const std::string& name) {
  if (name == "patchwork") return patchwork();
  std::string known;
  for (const auto& n : scene_names()) known += (known.empty() ? "" : ", ") + n;
  return make_error(ErrorCode::kInvalidArgument, "unknown scene \"" + name + "\"; known: " + known);
}

}  // namespace vdrig::sim

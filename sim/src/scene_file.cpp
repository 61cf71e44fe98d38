#include "vdrig/sim/scene_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <sstream>

#include "vdrig/core/image_io.hpp"
#include "vdrig/core/settings.hpp"

namespace vdrig::sim {
namespace {

using nlohmann::json;

std::string number_text(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

// One JSON object of the scene at `path` ("materials[2]"): Settings does the type checks and rejects unknown keys;
// the bounds are checked here so the message names the full path and the rule ("materials[2].shininess: must be
// >= 1, got 0"). Every problem ends up in `root`.
class ObjectReader {
 public:
  ObjectReader(Settings& root, const json& object, std::string path)
      : root_(root), object_(object), path_(std::move(path)), s_(object, path_) {}
  ~ObjectReader() {
    if (path_.empty())
      for (const auto& p : s_.problems()) root_.fail(p);
    else
      root_.absorb(s_);
  }
  ObjectReader(const ObjectReader&) = delete;
  ObjectReader& operator=(const ObjectReader&) = delete;

  const json& raw() const { return object_; }
  Settings& settings() { return s_; }
  std::string key_path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  void fail(const std::string& key, const std::string& rule) { root_.fail(key_path(key) + ": " + rule); }

  /// A number >= min (or > min when `strict`), at most max.
  double number(const std::string& key, double fallback, double min, bool strict = false,
                double max = std::numeric_limits<double>::max()) {
    const bool present = s_.has(key);
    const double x = s_.number(key, fallback);
    if (!present || !std::isfinite(x)) return x;
    check(key, x, min, strict, max);
    return x;
  }
  double required_number(const std::string& key) {
    if (!s_.has(key)) fail(key, "is required");
    return s_.number(key, 0.0);
  }
  /// n numbers, each in [min, max].
  std::vector<double> numbers(const std::string& key, std::vector<double> fallback, bool required,
                              double min = -std::numeric_limits<double>::max(),
                              double max = std::numeric_limits<double>::max()) {
    const std::size_t n = fallback.size();
    if (required && !s_.has(key)) fail(key, "is required");
    std::vector<double> v = s_.number_list(key, fallback, n);
    if (v.size() != n) return fallback;
    for (std::size_t i = 0; i < n; ++i)
      if (v[i] < min || v[i] > max) {
        fail(key + "[" + std::to_string(i) + "]", range_rule(min, false, max) + ", got " + number_text(v[i]));
        break;
      }
    return v;
  }
  Vec3d vec3(const std::string& key, const Vec3d& fallback, bool required = false,
             double min = -std::numeric_limits<double>::max(), double max = std::numeric_limits<double>::max()) {
    const auto v = numbers(key, {fallback.x(), fallback.y(), fallback.z()}, required, min, max);
    return {v[0], v[1], v[2]};
  }
  /// An index into materials: a number or a material's name.
  int material(const std::vector<Material>& materials) {
    const auto it = object_.find("material");
    if (it == object_.end()) {
      fail("material", "is required (an index or a material name)");
      return 0;
    }
    if (it->is_string()) {
      for (std::size_t i = 0; i < materials.size(); ++i)
        if (materials[i].name == it->get<std::string>()) return static_cast<int>(i);
      fail("material", "no material is named " + it->dump());
      return 0;
    }
    if (it->is_number_integer() || it->is_number_unsigned()) {
      const long long i = it->get<long long>();
      if (i >= 0 && i < static_cast<long long>(materials.size())) return static_cast<int>(i);
      fail("material", "must be an index in [0, " + std::to_string(materials.size()) + "), got " + it->dump());
      return 0;
    }
    fail("material", "must be an index or a material name, got " + it->dump());
    return 0;
  }

 private:
  static std::string range_rule(double min, bool strict, double max) {
    std::string rule = std::string("must be ") + (strict ? "> " : ">= ") + number_text(min);
    if (max < std::numeric_limits<double>::max()) rule += " and <= " + number_text(max);
    return rule;
  }
  void check(const std::string& key, double x, double min, bool strict, double max) {
    if (x < min || (strict && x == min) || x > max) fail(key, range_rule(min, strict, max) + ", got " + number_text(x));
  }

  Settings& root_;
  const json& object_;
  std::string path_;
  Settings s_;
};

// The objects of array `key` (an error when present and not an array of objects).
std::vector<json> objects(Settings& root, const json& j, const std::string& key, bool required) {
  const auto it = j.find(key);
  if (it == j.end()) {
    if (required) root.fail(key + ": is required");
    return {};
  }
  if (!it->is_array()) {
    root.fail(key + ": must be an array, got " + it->dump());
    return {};
  }
  return it->get<std::vector<json>>();
}

std::string indexed(const std::string& key, std::size_t i) { return key + "[" + std::to_string(i) + "]"; }

float srgb_to_linear(float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); }

// A kd image as linear RGB CV_32FC3: PNG (8-bit sRGB-decoded, 16-bit linear; grey or colour) or OpenEXR (linear;
// channels R, G, B or Y).
Result<cv::Mat> load_kd_image(const std::filesystem::path& file) {
  cv::Mat rgb;
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".exr") {
    auto exr = read_exr(file);
    if (!exr) return exr.error();
    const int r = exr->find("R"), g = exr->find("G"), b = exr->find("B"), y = exr->find("Y");
    if (r >= 0 && g >= 0 && b >= 0)
      cv::merge(std::vector<cv::Mat>{exr->channels[r], exr->channels[g], exr->channels[b]}, rgb);
    else if (y >= 0)
      cv::merge(std::vector<cv::Mat>{exr->channels[y], exr->channels[y], exr->channels[y]}, rgb);
    else
      return make_error(ErrorCode::kCorrupt, file.string() + " has neither R, G, B nor Y channels");
  } else if (ext == ".png") {
    auto png = read_png(file);
    if (!png) return png.error();
    cv::Mat colour;
    if (png->channels() == 1)
      cv::merge(std::vector<cv::Mat>{*png, *png, *png}, colour);
    else if (png->channels() == 3)
      colour = *png;
    else
      return make_error(ErrorCode::kCorrupt, file.string() + " must be a grey or RGB PNG");
    const bool eight_bit = colour.depth() == CV_8U;
    colour.convertTo(rgb, CV_32FC3, eight_bit ? 1.0 / 255.0 : 1.0 / 65535.0);
    if (eight_bit)
      rgb.forEach<cv::Vec3f>([](cv::Vec3f& p, const int*) {
        for (int c = 0; c < 3; ++c) p[c] = srgb_to_linear(p[c]);
      });
    std::vector<cv::Mat> bgr;
    cv::split(rgb, bgr);
    cv::merge(std::vector<cv::Mat>{bgr[2], bgr[1], bgr[0]}, rgb);
  } else {
    return make_error(ErrorCode::kInvalidArgument, "must be a .png or .exr file, got " + file.string());
  }
  double lo = 0;
  cv::minMaxLoc(rgb.reshape(1), &lo);
  if (!(lo >= 0)) return make_error(ErrorCode::kInvalidArgument, file.string() + " has negative or NaN values");
  return rgb;
}

Material read_material(Settings& root, const json& j, const std::string& path, std::size_t index,
                       const std::filesystem::path& base_dir) {
  ObjectReader r(root, j, path);
  r.settings().reject_unknown({"name", "kind", "kd", "kd_image", "ks", "shininess", "roughness", "roughness_y", "f0",
                               "bump_slope", "bump_period_mm", "printed", "ink_kd", "print_cell_mm"},
                              "field");
  Material m;
  m.name = r.settings().string("name", "material " + std::to_string(index));
  m.kind = r.settings().string("kind", "phong", {"phong", "ggx"}) == "ggx" ? MaterialKind::kGgx : MaterialKind::kPhong;
  m.kd = r.vec3("kd", m.kd, false, 0.0);
  m.ks = r.vec3("ks", m.ks, false, 0.0);
  m.shininess = r.number("shininess", m.shininess, 1.0);
  m.roughness = r.number("roughness", m.roughness, 0.0, true, 1.0);
  m.roughness_y = r.number("roughness_y", m.roughness_y, 0.0, false, 1.0);
  m.f0 = r.vec3("f0", m.f0, false, 0.0, 1.0);
  if (m.kind == MaterialKind::kGgx && !m.ks.isZero()) r.fail("ks", "is not used by a ggx material (its lobe is f0)");
  if (m.kind == MaterialKind::kPhong)
    for (const char* key : {"roughness", "roughness_y", "f0"})
      if (r.settings().has(key)) r.fail(key, "is only used by a ggx material (\"kind\": \"ggx\")");
  m.bump_slope = r.number("bump_slope", m.bump_slope, 0.0);
  m.bump_period_mm = r.number("bump_period_mm", m.bump_period_mm, 0.0, true);
  m.printed = r.settings().boolean("printed", m.printed);
  m.ink_kd = r.vec3("ink_kd", m.ink_kd, false, 0.0);
  m.print_cell_mm = r.number("print_cell_mm", m.print_cell_mm, 0.0, true);
  if (r.settings().has("kd_image")) {
    const std::string name = r.settings().required_string("kd_image");
    if (!name.empty()) {
      const std::filesystem::path file =
          std::filesystem::path(name).is_absolute() ? std::filesystem::path(name) : base_dir / name;
      auto image = load_kd_image(file);
      if (image) {
        m.kd_image = std::filesystem::absolute(file).lexically_normal().string();
        m.kd_texture = std::make_shared<const cv::Mat>(std::move(image.value()));
      } else {
        r.fail("kd_image", image.error().message);
      }
    }
  }
  return m;
}

}  // namespace

Result<Scene> parse_scene(const json& j, const std::string& source, const std::filesystem::path& base_dir) {
  Settings root(j, "scene " + source);
  if (!j.is_object()) return root.error();
  Scene s;
  {
    ObjectReader r(root, j, "");
    r.settings().reject_unknown({"format", "version", "name", "width_mm", "height_mm", "materials", "patches",
                                 "markers", "lights", "area_lights", "ambient"},
                                "field");
    if (r.settings().string("format", "", {"vdrig-scene"}).empty()) r.fail("format", "is required (\"vdrig-scene\")");
    if (!r.settings().has("version")) r.fail("version", "is required");
    const long long version = r.settings().integer("version", kSceneFormatVersion, 1, 1000000);
    if (version != kSceneFormatVersion)
      r.fail("version", "must be " + std::to_string(kSceneFormatVersion) + " (this vdrig's scene format), got " +
                            std::to_string(version));
    s.name = r.settings().string("name", source);
    if (!r.settings().has("width_mm")) r.fail("width_mm", "is required");
    if (!r.settings().has("height_mm")) r.fail("height_mm", "is required");
    s.width_mm = r.number("width_mm", s.width_mm, 0.0, true);
    s.height_mm = r.number("height_mm", s.height_mm, 0.0, true);
    s.ambient = r.vec3("ambient", s.ambient, false, 0.0);
  }
  const auto materials = objects(root, j, "materials", true);
  if (j.contains("materials") && materials.empty() && j["materials"].is_array())
    root.fail("materials: needs at least one material (materials[0] is the background)");
  for (std::size_t i = 0; i < materials.size(); ++i)
    s.materials.push_back(read_material(root, materials[i], indexed("materials", i), i, base_dir));

  const auto patches = objects(root, j, "patches", false);
  for (std::size_t i = 0; i < patches.size(); ++i) {
    ObjectReader r(root, patches[i], indexed("patches", i));
    r.settings().reject_unknown({"x0_mm", "y0_mm", "x1_mm", "y1_mm", "material"}, "field");
    Patch p{r.required_number("x0_mm"), r.required_number("y0_mm"), r.required_number("x1_mm"),
            r.required_number("y1_mm"), r.material(s.materials)};
    if (!(p.x0_mm < p.x1_mm))
      r.fail("x1_mm", "must be > x0_mm (" + number_text(p.x0_mm) + "), got " + number_text(p.x1_mm));
    if (!(p.y0_mm < p.y1_mm))
      r.fail("y1_mm", "must be > y0_mm (" + number_text(p.y0_mm) + "), got " + number_text(p.y1_mm));
    s.patches.push_back(p);
  }
  const auto markers = objects(root, j, "markers", false);
  for (std::size_t i = 0; i < markers.size(); ++i) {
    ObjectReader r(root, markers[i], indexed("markers", i));
    r.settings().reject_unknown({"centre_mm", "radius_mm", "material"}, "field");
    Disc d;
    const auto c = r.numbers("centre_mm", {0.0, 0.0}, true);
    d.centre_mm = Vec2d(c[0], c[1]);
    d.radius_mm = r.number("radius_mm", d.radius_mm, 0.0, true);
    d.material = r.material(s.materials);
    s.markers.push_back(d);
  }
  const auto lights = objects(root, j, "lights", false);
  for (std::size_t i = 0; i < lights.size(); ++i) {
    ObjectReader r(root, lights[i], indexed("lights", i));
    r.settings().reject_unknown({"position_mm", "intensity"}, "field");
    PointLight l;
    l.position_mm = r.vec3("position_mm", l.position_mm, true);
    l.intensity = r.vec3("intensity", l.intensity, false, 0.0);
    s.lights.push_back(l);
  }
  const auto area_lights = objects(root, j, "area_lights", false);
  for (std::size_t i = 0; i < area_lights.size(); ++i) {
    ObjectReader r(root, area_lights[i], indexed("area_lights", i));
    r.settings().reject_unknown({"centre_mm", "edge_u_mm", "edge_v_mm", "intensity", "samples_per_axis"}, "field");
    AreaLight a;
    a.centre_mm = r.vec3("centre_mm", a.centre_mm, true);
    a.edge_u_mm = r.vec3("edge_u_mm", a.edge_u_mm, true);
    a.edge_v_mm = r.vec3("edge_v_mm", a.edge_v_mm, true);
    a.intensity = r.vec3("intensity", a.intensity, false, 0.0);
    if (!r.settings().has("samples_per_axis") || r.raw()["samples_per_axis"].is_number()) {
      const double n = r.number("samples_per_axis", a.samples_per_axis, 1.0, false, 64.0);
      if (n != std::floor(n)) r.fail("samples_per_axis", "must be an integer, got " + number_text(n));
      a.samples_per_axis = static_cast<int>(std::clamp(n, 1.0, 64.0));
    } else {
      r.fail("samples_per_axis", "must be an integer, got " + r.raw()["samples_per_axis"].dump());
    }
    if (!(a.edge_u_mm.cross(a.edge_v_mm).norm() > 0)) r.fail("edge_v_mm", "must not be parallel to edge_u_mm");
    s.area_lights.push_back(a);
  }
  if (!root.is_valid(nullptr)) return root.error();
  std::string why;
  if (!s.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "scene " + source + ": " + why);
  return s;
}

Result<Scene> load_scene_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return make_error(ErrorCode::kIo, "cannot read scene file " + path);
  std::stringstream text;
  text << in.rdbuf();
  if (in.bad()) return make_error(ErrorCode::kIo, "cannot read scene file " + path);
  const json j = json::parse(text.str(), nullptr, false);
  if (j.is_discarded()) return make_error(ErrorCode::kInvalidArgument, "scene " + path + ": not valid JSON");
  return parse_scene(j, path, std::filesystem::path(path).parent_path());
}

nlohmann::ordered_json scene_to_json(const Scene& s) {
  using json = nlohmann::ordered_json;
  auto v3 = [](const Vec3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  const Material defaults;
  json materials = json::array();
  for (const Material& m : s.materials) {
    json o = {{"name", m.name}, {"kd", v3(m.kd)}};
    if (!m.kd_image.empty()) o["kd_image"] = m.kd_image;
    if (m.kind == MaterialKind::kGgx) {
      o["kind"] = "ggx";
      o["roughness"] = m.roughness;
      if (m.roughness_y != defaults.roughness_y) o["roughness_y"] = m.roughness_y;
      o["f0"] = v3(m.f0);
    } else {
      o["ks"] = v3(m.ks);
      o["shininess"] = m.shininess;
    }
    if (m.kind == MaterialKind::kGgx && m.shininess != defaults.shininess) o["shininess"] = m.shininess;
    if (m.bump_slope != defaults.bump_slope) o["bump_slope"] = m.bump_slope;
    if (m.bump_period_mm != defaults.bump_period_mm) o["bump_period_mm"] = m.bump_period_mm;
    if (m.printed) o["printed"] = true;
    if (m.ink_kd != defaults.ink_kd) o["ink_kd"] = v3(m.ink_kd);
    if (m.print_cell_mm != defaults.print_cell_mm) o["print_cell_mm"] = m.print_cell_mm;
    materials.push_back(o);
  }
  json patches = json::array();
  for (const Patch& p : s.patches)
    patches.push_back(
        {{"x0_mm", p.x0_mm}, {"y0_mm", p.y0_mm}, {"x1_mm", p.x1_mm}, {"y1_mm", p.y1_mm}, {"material", p.material}});
  json markers = json::array();
  for (const Disc& d : s.markers)
    markers.push_back({{"centre_mm", json::array({d.centre_mm.x(), d.centre_mm.y()})},
                       {"radius_mm", d.radius_mm},
                       {"material", d.material}});
  json lights = json::array();
  for (const PointLight& l : s.lights)
    lights.push_back({{"position_mm", v3(l.position_mm)}, {"intensity", v3(l.intensity)}});
  json area_lights = json::array();
  for (const AreaLight& a : s.area_lights)
    area_lights.push_back({{"centre_mm", v3(a.centre_mm)},
                           {"edge_u_mm", v3(a.edge_u_mm)},
                           {"edge_v_mm", v3(a.edge_v_mm)},
                           {"intensity", v3(a.intensity)},
                           {"samples_per_axis", a.samples_per_axis}});
  json j = {
      {"format", "vdrig-scene"},  {"version", kSceneFormatVersion}, {"name", s.name},     {"width_mm", s.width_mm},
      {"height_mm", s.height_mm}, {"materials", materials},         {"patches", patches}, {"markers", markers},
      {"lights", lights}};
  if (!s.area_lights.empty()) j["area_lights"] = area_lights;
  if (!s.ambient.isZero()) j["ambient"] = v3(s.ambient);
  return j;
}

Status save_scene_file(const Scene& scene, const std::string& path) {
  // One line per material, patch, marker and light: a scene file stays readable and diffable.
  const nlohmann::ordered_json j = scene_to_json(scene);
  std::ofstream out(path);
  out << "{";
  const char* separator = "\n";
  for (const auto& [key, value] : j.items()) {
    out << separator << "  " << nlohmann::json(key).dump() << ": ";
    if (value.is_array() && !value.empty() && value.front().is_object()) {
      out << "[";
      for (std::size_t i = 0; i < value.size(); ++i) out << (i ? ",\n    " : "\n    ") << value[i].dump();
      out << "\n  ]";
    } else {
      out << value.dump();
    }
    separator = ",\n";
  }
  out << "\n}\n";
  out.close();
  if (!out) return make_error(ErrorCode::kIo, "cannot write scene file " + path);
  return Status::ok();
}

}  // namespace vdrig::sim

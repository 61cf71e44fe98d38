// PhongModel itself: names, channels, evaluation, GLSL, what it says about a texel, its options. Its map fit is in
// phong_map_fit.cpp (staged texels, the shared-lights pass), its tiled fit in phong_tile_records.cpp.
#include "vdrig/fitting/phong_model.hpp"

#include <cmath>

#include <fmt/format.h>

#include "phong_map_fit.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {
namespace {

const char* kRgb[3] = {"R", "G", "B"};
const char* kXyz[3] = {"x", "y", "z"};
using phong_map_fit::kMaxLobes;

std::string lobe_channel(const char* base, int k, const char* c) {
  return std::string(base) + std::to_string(k) + "." + c;
}

/// Parameter offsets of the layout of PhongModel::channels().
struct Layout {
  int lobes;
  bool shared;
  int per_lobe() const { return shared ? 6 : 7; }
  int ks(int k, int c) const { return 3 + per_lobe() * k + c; }
  int direction(int k, int c) const { return 3 + per_lobe() * k + 3 + c; }
  int shininess(int k) const { return shared ? 3 + 6 * lobes : 3 + 7 * k + 6; }
};

Result<ModelPtr> parse_phong(const std::string& settings) {
  const auto colon = settings.find(':');
  std::string lobes = settings.substr(0, colon);
  const std::string option = colon == std::string::npos ? "" : settings.substr(colon + 1);
  if (!option.empty() && option != "per-lobe-m")
    return make_error(ErrorCode::kInvalidArgument, "unknown option \"" + option + "\"");
  if (lobes.empty()) lobes = "1";
  const bool shared = option.empty();
  if (lobes == "auto") return ModelPtr(std::make_shared<PhongModel>(0, true, shared));
  if (lobes.size() != 1 || lobes[0] < '1' || lobes[0] > '0' + kMaxLobes)
    return make_error(ErrorCode::kInvalidArgument, "lobes must be 1..4 or auto");
  return ModelPtr(std::make_shared<PhongModel>(lobes[0] - '0', false, shared));
}

}  // namespace

PhongModel::PhongModel(int lobes, bool auto_lobes, bool shared_shininess)
    : lobes_(lobes), auto_lobes_(auto_lobes), shared_shininess_(shared_shininess) {
  VDRIG_CHECK(lobes >= (auto_lobes ? 0 : 1) && lobes <= kMaxLobes, "PhongModel: lobes out of range");
}

ModelPtr PhongModel::with_lobes(int lobes) const {
  return std::make_shared<PhongModel>(lobes, auto_lobes_, shared_shininess_);
}

std::string PhongModel::name() const {
  return "phong:" + (auto_lobes_ ? std::string("auto") : std::to_string(lobes_)) +
         (shared_shininess_ ? "" : ":per-lobe-m");
}

std::vector<std::string> PhongModel::channels() const {
  std::vector<std::string> names;
  for (auto c : kRgb) names.push_back(std::string("kd.") + c);
  for (int k = 0; k < lobes_; ++k) {
    for (auto c : kRgb) names.push_back(lobe_channel("ks", k, c));
    for (auto c : kXyz) names.push_back(lobe_channel("r", k, c));
    if (!shared_shininess_) names.push_back("m" + std::to_string(k));
  }
  if (shared_shininess_) names.push_back("m");
  if (auto_lobes_) names.push_back("lobes");
  return names;
}

void PhongModel::write_attributes(std::map<std::string, double>& number_attributes) const {
  number_attributes["vdrig.lobes"] = lobes_;
  number_attributes["vdrig.shared_m"] = shared_shininess_ ? 1 : 0;
}

Result<ModelPtr> PhongModel::with_attributes(const std::map<std::string, double>& number_attributes) const {
  if (!auto_lobes_) return shared_from_this();
  const auto it = number_attributes.find("vdrig.lobes");
  // Checked as a double first: casting NaN or 1e300 to int is undefined behaviour (found by fuzz_parameter_map).
  const double lobes = it == number_attributes.end() ? 0.0 : it->second;
  if (!(lobes >= 1 && lobes <= kMaxLobes)) return make_error(ErrorCode::kCorrupt, "bad vdrig.lobes");
  return with_lobes(static_cast<int>(lobes));
}

PhongParams PhongModel::params_of(std::span<const double> p) const {
  VDRIG_CHECK(static_cast<int>(p.size()) == parameter_count(), "PhongModel: wrong parameter count");
  const Layout at{lobes_, shared_shininess_};
  PhongParams params;
  for (int c = 0; c < 3; ++c) params.kd[c] = p[c];
  for (int k = 0; k < lobes_; ++k) {
    PhongLobe l;
    for (int c = 0; c < 3; ++c) {
      l.ks[c] = p[at.ks(k, c)];
      l.direction[c] = p[at.direction(k, c)];
    }
    l.shininess = p[at.shininess(k)];
    params.lobes.push_back(l);
  }
  return params;
}

std::vector<double> PhongModel::parameters_of(const PhongParams& params) const {
  VDRIG_CHECK(static_cast<int>(params.lobes.size()) <= lobes_, "Phong lobes exceed the map's");
  const Layout at{lobes_, shared_shininess_};
  std::vector<double> p(static_cast<size_t>(parameter_count()), 0.0);
  for (int c = 0; c < 3; ++c) p[c] = params.kd[c];
  for (int k = 0; k < lobes_; ++k) {
    // A texel that needs fewer lobes than the map stores has zero energy in the rest.
    const PhongLobe lobe = k < static_cast<int>(params.lobes.size()) ? params.lobes[k] : PhongLobe{};
    for (int c = 0; c < 3; ++c) {
      p[at.ks(k, c)] = lobe.ks[c];
      p[at.direction(k, c)] = lobe.direction[c];
    }
    if (!shared_shininess_) p[at.shininess(k)] = lobe.shininess;
  }
  if (shared_shininess_) p[at.shininess(0)] = params.lobes.empty() ? 1.0 : params.lobes[0].shininess;
  if (auto_lobes_) p.back() = static_cast<double>(params.lobes.size());
  return p;
}

std::string PhongModel::check_parameters(std::span<const double> parameters) const {
  const Layout layout{lobes_, shared_shininess_};
  for (int k = 0; k < (shared_shininess_ ? 1 : lobes_); ++k) {
    const double m = parameters[layout.shininess(k)];
    if (m < 0) return "Phong exponent " + channels()[layout.shininess(k)] + " is negative (" + std::to_string(m) + ")";
  }
  return {};
}

Vec3d PhongModel::evaluate(std::span<const double> parameters, const Vec3d& v) const {
  return params_of(parameters).evaluate(v);
}

std::string PhongModel::glsl(const std::function<std::string(int parameter)>& parameter) const {
  const Layout at{lobes_, shared_shininess_};
  auto vec3 = [&](int i0, int i1, int i2) {
    return "vec3(" + parameter(i0) + ", " + parameter(i1) + ", " + parameter(i2) + ")";
  };
  std::string s = "vec3 model(ivec2 t, vec3 v) {\n";
  s += "  vec3 I = " + vec3(0, 1, 2) + ";\n";
  for (int k = 0; k < lobes_; ++k) {
    s += "  {\n    vec3 r = " + vec3(at.direction(k, 0), at.direction(k, 1), at.direction(k, 2)) + ";\n";
    s += "    vec3 ks = " + vec3(at.ks(k, 0), at.ks(k, 1), at.ks(k, 2)) + ";\n";
    s +=
        "    float c = dot(v, r);\n    if (c > 0.0) I += ks * exp(" + parameter(at.shininess(k)) + " * log(c));\n  }\n";
  }
  s += "  return I;\n}\n";
  return s;
}

Vec3d PhongModel::diffuse_part(std::span<const double> parameters) const { return params_of(parameters).kd; }

std::vector<LobeSummary> PhongModel::lobes(std::span<const double> parameters) const {
  std::vector<LobeSummary> out;
  for (const PhongLobe& lobe : params_of(parameters).lobes) out.push_back({lobe.ks, lobe.direction, lobe.shininess});
  return out;
}

std::vector<double> PhongModel::sample_parameters(unsigned seed) const {
  VDRIG_CHECK(storable(), "sample_parameters of " + name() + " before its lobe count is known");
  const double phase = 0.7 * static_cast<double>(seed);
  PhongParams p;
  p.kd = Vec3d(0.3 + 0.1 * std::sin(phase), 0.25, 0.2 + 0.05 * std::cos(phase));
  for (int k = 0; k < lobes_; ++k) {
    PhongLobe lobe;
    lobe.ks = Vec3d(0.8, 0.7, 0.6) / (k + 1);
    // Lobes spread in azimuth, 20..45 degrees from the normal.
    lobe.direction = direction_from_spherical(phase + 2.0 * k, deg_to_rad(20.0 + 8.0 * k + 5.0 * std::sin(phase)));
    lobe.shininess = shared_shininess_ ? 20.0 : 10.0 + 15.0 * k;
    p.lobes.push_back(lobe);
  }
  return parameters_of(p);
}

Status PhongModel::check_options(const MapFitOptions& options) const {
  const PhongFitOptions phong = phong_map_fit::texel_fit_options(*this, options);
  std::string why;
  if (!phong.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  if (options.shared_lights) {
    if (!phong.fixed_directions.empty())
      return make_error(ErrorCode::kInvalidArgument, "shared_lights sets each texel's directions itself");
    if (!options.lights.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  }
  if (auto_lobes_ && !phong.fixed_directions.empty())
    return make_error(ErrorCode::kInvalidArgument, "phong:auto does not take fixed directions");
  return Status::ok();
}

std::string PhongModel::options_fingerprint(const MapFitOptions& options) const {
  std::string s = phong_map_fit::texel_fit_options(*this, options).fingerprint();
  if (options.shared_lights) {
    const LightEstimationOptions& l = options.lights;
    s += fmt::format(";lights=max:{},inlier:{},exclusion:{},min_inliers:{},iterations:{},max_distance:{},seed:{}",
                     l.max_lights, l.inlier_angle_rad, l.exclusion_angle_rad, l.min_inliers, l.ransac_iterations,
                     l.max_distance_mm, l.seed);
  }
  return s;
}

void register_phong_model(ModelRegistry& registry) {
  registry.add(
      {"phong",
       "phong:K|phong:K:per-lobe-m|phong:auto|phong:auto:per-lobe-m",
       parse_phong,
       {"phong:1", "phong:2", "phong:3", "phong:4", "phong:auto", "phong:2:per-lobe-m", "phong:auto:per-lobe-m"}});
}

PhongParams phong_texel(const ParameterMap& map, int s, int t) {
  const auto* phong = dynamic_cast<const PhongModel*>(&map.model());
  VDRIG_CHECK(phong, "phong_texel on a " + map.model().name() + " map");
  return phong->params_of(map.parameters(s, t));
}

void set_phong_texel(ParameterMap& map, int s, int t, const PhongParams& params) {
  const auto* phong = dynamic_cast<const PhongModel*>(&map.model());
  VDRIG_CHECK(phong, "set_phong_texel on a " + map.model().name() + " map");
  map.set_parameters(s, t, phong->parameters_of(params));
}

}  // namespace vdrig::fitting

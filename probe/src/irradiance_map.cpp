#include "vdrig/probe/irradiance_map.hpp"

#include <algorithm>
#include <cstdlib>
#include <numeric>

namespace vdrig::probe {
namespace {

Result<int> parse_count(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const long n = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || n < 1 || n > (1 << 20))
    return make_error(ErrorCode::kInvalidArgument,
                      what + " needs a light count >= 1 after the colon, got '" + text + "'");
  return static_cast<int>(n);
}

}  // namespace

Result<IrradianceMethodSpec> parse_irradiance_method(const std::string& text) {
  IrradianceMethodSpec s;
  if (text == "exact") return s;
  if (text == "sh9") {
    s.method = IrradianceMethod::kSh9;
    return s;
  }
  const size_t colon = text.find(':');
  const std::string name = text.substr(0, colon);
  if ((name == "mediancut" || name == "hybrid" || name == "soft") && colon != std::string::npos) {
    auto n = parse_count(text.substr(colon + 1), name);
    if (!n) return n.error();
    s.method = name == "mediancut" ? IrradianceMethod::kMedianCut
                                   : (name == "hybrid" ? IrradianceMethod::kHybrid : IrradianceMethod::kSoft);
    s.light_count = *n;
    if (s.method == IrradianceMethod::kMedianCut && !is_power_of_two(s.light_count))
      return make_error(ErrorCode::kInvalidArgument,
                        "mediancut:N needs N a power of two, got " + std::to_string(s.light_count));
    return s;
  }
  return make_error(ErrorCode::kInvalidArgument,
                    "irradiance method must be exact, sh9, mediancut:N, hybrid:N or soft:N, got '" + text + "'");
}

std::string to_string(const IrradianceMethodSpec& s) {
  switch (s.method) {
    case IrradianceMethod::kExact:
      return "exact";
    case IrradianceMethod::kSh9:
      return "sh9";
    case IrradianceMethod::kMedianCut:
      return "mediancut:" + std::to_string(s.light_count);
    case IrradianceMethod::kHybrid:
      return "hybrid:" + std::to_string(s.light_count);
    case IrradianceMethod::kSoft:
      return "soft:" + std::to_string(s.light_count);
  }
  return "?";
}

IrradianceModel IrradianceModel::from_latlong_cut(const Probe& probe, const IrradianceMethodSpec& spec) {
  IrradianceModel m;
  if (spec.method == IrradianceMethod::kMedianCut) {
    m.lights_ = median_cut(probe, spec.light_count);
    return m;
  }
  if (spec.method == IrradianceMethod::kSoft) {
    SoftLightOptions o;
    o.count = spec.light_count;
    m.soft_ = soft_lights(probe, o);
    m.sh9_ = m.soft_->sh9;
    return m;
  }
  VDRIG_CHECK(spec.method == IrradianceMethod::kHybrid && spec.light_count >= 1, "hybrid needs a light count");
  m.soft_ = hybrid_lights(probe, spec.light_count);
  m.sh9_ = m.soft_->sh9;
  return m;
}

IrradianceModel IrradianceModel::build(const Probe& probe, const IrradianceMethodSpec& spec) {
  switch (spec.method) {
    case IrradianceMethod::kExact: {
      IrradianceModel m;
      m.exact_.emplace(probe);
      return m;
    }
    case IrradianceMethod::kSh9: {
      IrradianceModel m;
      m.sh9_ = project_sh9(probe);
      return m;
    }
    default:
      return from_latlong_cut(probe, spec);
  }
}

IrradianceModel IrradianceModel::build(const CubeMap& cube, const IrradianceMethodSpec& spec) {
  if (spec.method == IrradianceMethod::kMedianCut || spec.method == IrradianceMethod::kHybrid ||
      spec.method == IrradianceMethod::kSoft)
    return from_latlong_cut(cube_to_latlong(cube, 2 * cube.size), spec);
  std::vector<Vec3d> dirs;
  std::vector<Rgb> weighted;
  cube_quadrature(cube, &dirs, &weighted);
  IrradianceModel m;
  if (spec.method == IrradianceMethod::kExact)
    m.exact_.emplace(dirs, weighted);
  else
    m.sh9_ = project_sh9(dirs, weighted);
  return m;
}

Rgb IrradianceModel::irradiance(const Vec3d& normal) const {
  if (exact_) return exact_->irradiance(normal);
  if (soft_) return soft_->irradiance(normal);
  Rgb e = irradiance_from_lights(lights_, normal);
  if (sh9_) e += sh9_irradiance(*sh9_, normal);
  return e;
}

Probe irradiance_latlong(const IrradianceModel& model, int width) {
  VDRIG_CHECK(width >= 2 && width % 2 == 0, "irradiance map width must be even and >= 2");
  Probe out = make_probe(width / 2);
  for (int j = 0; j < out.height(); ++j)
    for (int i = 0; i < out.width(); ++i)
      out.radiance.at<cv::Vec3f>(j, i) =
          to_bgr(model.irradiance(latlong_direction(i, j, out.width(), out.height())).cwiseMax(0.0));
  return out;
}

CubeMap irradiance_cube(const IrradianceModel& model, int size) {
  CubeMap out = make_cube_map(size);
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < size; ++j)
      for (int i = 0; i < size; ++i)
        out.faces[f].at<cv::Vec3f>(j, i) =
            to_bgr(model.irradiance(cube_direction(static_cast<CubeFace>(f), i + 0.5, j + 0.5, size)).cwiseMax(0.0));
  return out;
}

}  // namespace vdrig::probe

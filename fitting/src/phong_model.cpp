#include "vdrig/fitting/phong_model.hpp"

#include <algorithm>
#include <atomic>
#include <limits>

#include <fmt/format.h>

#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {
namespace {

const char* kRgb[3] = {"R", "G", "B"};
const char* kXyz[3] = {"x", "y", "z"};
constexpr int kMaxLobes = 4;

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

/// A texel's Phong fit, kept until the map's lobe count is known (phong:auto) and the shared-lights pass has run.
struct StagedPhong {
  PhongParams params;
  FitQuality quality;
  Vec3d holdout = Vec3d::Zero();
  double bic = std::numeric_limits<double>::infinity();  // of the fit as minimised (phong_bic)
  bool shared_lights = false;                            // directions from the estimated lights
};

/// BIC of a fit of `obs` (as phong_bic: RSS of the residuals as minimised = 2 cost, n = 3 x observations).
double fit_bic(const PhongFit& fit, const TexelObservations& obs, int parameters) {
  const int n = static_cast<int>(3 * obs.size());
  double sq = 0;
  for (size_t i = 0; i < obs.size(); ++i) sq += obs.radiance[i].cast<double>().squaredNorm();
  return phong_bic(2.0 * fit.cost, n, parameters, std::sqrt(sq / std::max(1, n)));
}

/// Rays toward the lights from every texel whose fitted lobes carry energy (lights.hpp), at most `max_rays`
/// (an even subsample: RANSAC needs many rays, not all of a 512 x 512 map's).
std::vector<LobeRay> lobe_rays(const std::vector<StagedPhong>& staged, const ObservationMapSpec& spec,
                               size_t max_rays) {
  std::vector<LobeRay> rays;
  for (size_t i = 0; i < staged.size(); ++i) {
    const PhongParams& p = staged[i].params;
    const int s = static_cast<int>(i % spec.texels_s), t = static_cast<int>(i / spec.texels_s);
    for (const PhongLobe& lobe : p.lobes)
      // A lobe far below the diffuse level is the fit's way of saying "no highlight": its direction is noise.
      if (lobe.ks.maxCoeff() > 1e-3 * std::max(p.kd.maxCoeff(), 1e-12))
        rays.push_back(lobe_ray(texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm),
                                lobe.direction));
  }
  if (rays.size() <= max_rays) return rays;
  std::vector<LobeRay> subsample;
  for (size_t k = 0; k < max_rays; ++k) subsample.push_back(rays[k * rays.size() / max_rays]);
  return subsample;
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

Result<ParameterMap> PhongModel::fit_map(const MapFitContext& context) const {
  const MapFitOptions& options = context.options;
  const ObservationMapSpec& spec = context.spec;
  PhongFitOptions phong = options.phong;
  phong.lobes = auto_lobes_ ? kMaxLobes : lobes_;
  phong.shared_shininess = shared_shininess_;
  std::string why;
  if (!phong.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  if (options.shared_lights) {
    if (!options.phong.fixed_directions.empty())
      return make_error(ErrorCode::kInvalidArgument, "shared_lights sets each texel's directions itself");
    if (!options.lights.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  }
  if (auto_lobes_ && !options.phong.fixed_directions.empty())
    return make_error(ErrorCode::kInvalidArgument, "phong:auto does not take fixed directions");

  const int total = spec.texels_s * spec.texels_t;
  const bool shared_lights = options.shared_lights;
  const int passes = shared_lights ? 2 : 1;
  const bool holding_out = !options.held_out.empty();

  // Texels are staged and the map built at the end: phong:auto learns the map's lobe count only then, and the
  // shared-lights pass may replace a texel's fit.
  std::vector<StagedPhong> staged(total);

  // Pass 1: every texel on its own.
  auto fit_texel = [&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
    const bool enough = static_cast<int>(texel.size()) >= options.min_observations;
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    StagedPhong& st = staged[static_cast<size_t>(t) * spec.texels_s + s];
    if (enough) {
      const PhongFit fit = auto_lobes_ ? fit_phong_auto(texel, phong, kMaxLobes) : fit_phong(texel, phong);
      st.params = fit.params;
      q = fit.quality;
      if (held.size()) hq = measure_quality(fit.params, held);
      st.bic = fit_bic(fit, texel,
                       phong_parameter_count(static_cast<int>(fit.params.lobes.size()), phong.shared_shininess,
                                             !phong.fixed_directions.empty()));
    }
    st.quality = q;
    st.holdout = hq.rms;
  };
  VDRIG_TRY(context.for_each_texel(0, passes, fit_texel));

  // Pass 2 (shared lights): the lights from every texel's lobes, then each texel refitted with its lobes pointing at
  // them; the refit replaces the free fit where its BIC is lower (it has 2 parameters fewer per lobe, so it wins
  // wherever it fits as well, and loses where the texel's normal or light differs, e.g. a bumpy patch).
  std::string lights_attribute;
  if (shared_lights) {
    LightEstimationOptions light_options = options.lights;
    light_options.max_lights = std::min(light_options.max_lights, auto_lobes_ ? kMaxLobes : phong.lobes);
    auto lights = estimate_point_lights(lobe_rays(staged, spec, 20000), light_options);
    if (!lights) return lights.error();
    auto logger = log::get("fitting");
    if (lights->empty()) {
      logger->warn("shared lights: no light explains enough texels' lobes; every texel keeps its own fit");
    } else {
      for (const EstimatedLight& l : lights.value()) {
        const Vec3d& v = l.at_infinity ? l.direction : l.position_mm;
        lights_attribute += fmt::format("{}{} {:.3f} {:.3f} {:.3f}", lights_attribute.empty() ? "" : "; ",
                                        l.at_infinity ? "direction" : "point", v.x(), v.y(), v.z());
      }
      for (const EstimatedLight& l : lights.value())
        if (l.at_infinity)
          logger->info("shared lights: distant light toward ({:.3f}, {:.3f}, {:.3f}), {} texel lobes, rms {:.2f} deg",
                       l.direction.x(), l.direction.y(), l.direction.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
        else
          logger->info("shared lights: point light at ({:.1f}, {:.1f}, {:.1f}) mm, {} texel lobes, rms {:.2f} deg",
                       l.position_mm.x(), l.position_mm.y(), l.position_mm.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
      std::atomic<int> replaced{0};
      auto refit_texel = [&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
        if (static_cast<int>(texel.size()) < options.min_observations) return;
        const Vec3d p = texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
        PhongFitOptions fixed = phong;
        fixed.lobes = static_cast<int>(lights->size());
        fixed.fixed_directions.clear();
        for (const EstimatedLight& l : lights.value()) fixed.fixed_directions.push_back(mirror_direction_at(l, p));
        // A light below the texel's horizon leaves no highlight to fit: keep the free fit.
        for (const Vec3d& d : fixed.fixed_directions)
          if (!(d.z() >= 0.0)) return;
        const PhongFit fit = fit_phong(texel, fixed);
        const double bic = fit_bic(fit, texel, phong_parameter_count(fixed.lobes, fixed.shared_shininess, true));
        StagedPhong& st = staged[static_cast<size_t>(t) * spec.texels_s + s];
        if (!(bic <= st.bic)) return;
        st.params = fit.params;
        st.quality = fit.quality;
        st.holdout = held.size() ? measure_quality(fit.params, held).rms : Vec3d::Zero();
        st.bic = bic;
        st.shared_lights = true;
        replaced.fetch_add(1);
      };
      VDRIG_TRY(context.for_each_texel(1, passes, refit_texel));
      logger->info("shared lights: {} of {} texels fitted with the lights' directions", replaced.load(), total);
    }
  }

  int map_lobes = lobes_;
  if (auto_lobes_) {
    map_lobes = 1;
    for (const auto& st : staged) map_lobes = std::max(map_lobes, static_cast<int>(st.params.lobes.size()));
  }
  const auto model = std::static_pointer_cast<const PhongModel>(with_lobes(map_lobes));
  ParameterMap map(model, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  if (shared_lights) {
    map.add_channel("shared_lights");
    map.image().string_attributes["vdrig.shared_lights"] = lights_attribute;
  }
  for (int i = 0; i < total; ++i) {
    const int s = i % spec.texels_s, t = i / spec.texels_s;
    map.set_parameters(s, t, model->parameters_of(staged[i].params));
    if (shared_lights) map.at("shared_lights", s, t) = staged[i].shared_lights ? 1.0f : 0.0f;
    map.set_quality(s, t, staged[i].quality);
    if (holding_out) map.set_holdout_rms(s, t, staged[i].holdout);
  }
  return map;
}

void register_phong_model(ModelRegistry& registry) { registry.add({"phong", "phong:K|phong:auto", parse_phong}); }

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

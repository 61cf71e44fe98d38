#include "vdrig/fitting/model.hpp"

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/fitting/harmonic_model.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/fitting/ptm_model.hpp"

namespace vdrig::fitting {

void register_builtin_models(ModelRegistry& registry) {
  register_phong_model(registry);
  register_harmonic_models(registry);
  register_ptm_model(registry);
  register_ggx_model(registry);
}

void ReflectanceModel::write_attributes(std::map<std::string, double>&) const {}

Result<ModelPtr> ReflectanceModel::with_attributes(const std::map<std::string, double>&) const {
  return shared_from_this();
}

Vec3d ReflectanceModel::diffuse_part(std::span<const double>) const {
  VDRIG_CHECK(false, "model " + name() + " has no diffuse part (has_diffuse_part() is false)");
  return Vec3d::Zero();
}

Vec3d ReflectanceModel::peak_direction(std::span<const double> parameters) const {
  const LobeSummary* best = nullptr;
  const std::vector<LobeSummary> lobes_of_texel = lobes(parameters);
  for (const LobeSummary& lobe : lobes_of_texel)
    if (!best || lobe.peak_rgb.sum() > best->peak_rgb.sum()) best = &lobe;
  if (best && best->peak_rgb.sum() > 0) return best->direction.normalized();
  Vec3d brightest = Vec3d::UnitZ();
  double brightest_value = evaluate(parameters, brightest).mean();
  for (int zen = 1; zen <= 89; ++zen)
    for (int az = 0; az < 360; az += 2) {
      const Vec3d d = direction_from_spherical(deg_to_rad(az), deg_to_rad(zen));
      const double v = evaluate(parameters, d).mean();
      if (v > brightest_value) {
        brightest_value = v;
        brightest = d;
      }
    }
  return brightest;
}

Status ReflectanceModel::check_options(const MapFitOptions& options) const {
  if (options.shared_lights)
    return make_error(ErrorCode::kInvalidArgument, "shared_lights applies to Phong models only, not " + family());
  return Status::ok();
}

Result<LinearFitOperator> ReflectanceModel::fit_operator(const std::vector<Vec3d>&, const MapFitOptions&) const {
  return make_error(ErrorCode::kUnsupported, "model " + name() + " is not linear in shared directions");
}

Result<ParameterMap> fit_map_per_texel(const ModelPtr& model, const MapFitContext& context,
                                       const std::function<std::unique_ptr<TexelFitter>()>& make_fitter) {
  const MapFitOptions& options = context.options;
  VDRIG_TRY(model->check_options(options));
  const ObservationMapSpec& spec = context.spec;
  const bool holding_out = !options.held_out.empty();
  ParameterMap map(model, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  if (holding_out) map.set_holdout_rms(0, 0, Vec3d::Zero());  // channels before threads
  const bool loo = model->reports_leave_one_out();
  if (loo)
    for (const char* c : kLeaveOneOutChannels) map.add_channel(c);
  // One fitter per worker, made on first use.
  std::vector<std::unique_ptr<TexelFitter>> fitters(static_cast<size_t>(context.workers));
  auto fit_texel = [&](int worker, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    // Distinct texels: no two threads write the same map element.
    if (static_cast<int>(texel.size()) >= options.min_observations) {
      auto& fitter = fitters[static_cast<size_t>(worker)];
      if (!fitter) fitter = make_fitter();
      const std::vector<double> p = fitter->fit(texel);
      map.set_parameters(s, t, p);
      Vec3d loo_rms = Vec3d::Zero();
      if (!fitter->quality(texel, p, &q, &loo_rms)) q = measure_quality(*model, p, texel);
      if (loo)
        for (int c = 0; c < 3; ++c) map.at(kLeaveOneOutChannels[c], s, t) = static_cast<float>(loo_rms[c]);
      if (held.size()) hq = measure_quality(*model, p, held);
    }
    map.set_quality(s, t, q);
    if (holding_out) map.set_holdout_rms(s, t, hq.rms);
  };
  VDRIG_TRY(context.for_each_texel(0, 1, fit_texel));
  return map;
}

void ModelRegistry::add(Entry entry) {
  for (const Entry& e : entries_) VDRIG_CHECK(e.family != entry.family, "model " + entry.family + " registered twice");
  VDRIG_CHECK(!entry.family.empty() && entry.family.find(':') == std::string::npos && entry.parse,
              "a model family needs a name without ':' and a parser");
  // The examples are how the tests reach a family (test_models, test_render_models): none would leave it unchecked.
  VDRIG_CHECK(!entry.examples.empty(), "model " + entry.family + " registered without example names");
  entries_.push_back(std::move(entry));
}

Result<ModelPtr> ModelRegistry::parse(const std::string& name) const {
  const auto colon = name.find(':');
  const std::string family = name.substr(0, colon);
  const std::string settings = colon == std::string::npos ? "" : name.substr(colon + 1);
  auto bad = [&](const std::string& why) {
    return make_error(ErrorCode::kInvalidArgument,
                      "model \"" + name + "\": " + why + " (expected " + syntax("|") + ")");
  };
  for (const Entry& e : entries_) {
    if (e.family != family) continue;
    auto model = e.parse(settings);
    if (!model) return bad(model.error().message);
    return model;
  }
  return bad("unknown model");
}

std::vector<std::string> ModelRegistry::families() const {
  std::vector<std::string> names;
  for (const Entry& e : entries_) names.push_back(e.family);
  return names;
}

std::vector<std::string> ModelRegistry::examples() const {
  std::vector<std::string> names;
  for (const Entry& e : entries_) names.insert(names.end(), e.examples.begin(), e.examples.end());
  return names;
}

std::string ModelRegistry::syntax(const std::string& separator) const {
  std::string s;
  for (const Entry& e : entries_) {
    std::string part = e.syntax;
    // An entry's syntax may list alternatives with '|': they take the separator too.
    for (size_t p = part.find('|'); p != std::string::npos; p = part.find('|', p + separator.size()))
      part.replace(p, 1, separator);
    s += (s.empty() ? "" : separator) + part;
  }
  return s;
}

const ModelRegistry& model_registry() {
  static const ModelRegistry registry = [] {
    ModelRegistry r;
    register_builtin_models(r);
    return r;
  }();
  return registry;
}

Result<ModelPtr> parse_model(const std::string& name) { return model_registry().parse(name); }

}  // namespace vdrig::fitting

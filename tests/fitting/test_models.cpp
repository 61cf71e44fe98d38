// The model registry and the ReflectanceModel interface, on every example name every registered family gives
// (ModelRegistry::examples: a new model is checked here without editing this file): names parse and print back the
// same, bad names are rejected with the reason, channel names are unique, sample parameters are a plausible texel,
// what a model says about a texel (diffuse part, lobes, peak, basis) agrees with its radiance, options are checked
// and fingerprinted by the model; a model defined outside the registry's built-ins (here, in the test) fits and
// stores a map through the same interface.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/fitting/tiled_fit.hpp"

namespace vdrig::fitting {
namespace {

/// Every spelling of every built-in family that the tests below go through: the examples each family registers
/// (ModelRegistry::Entry::examples), so that a new model is checked here without editing this file.
std::vector<std::string> names() { return model_registry().examples(); }

std::string family_of(const std::string& name) { return name.substr(0, name.find(':')); }

/// The model of `name` in a form a map can hold (phong:auto with a lobe count).
ModelPtr storable_model(const std::string& name) {
  ModelPtr model = parse_model(name).value();
  return model->storable() ? model : model->storable_sample();
}

TEST(ModelRegistry, EveryRegisteredFamilyHasExamplesOfItsOwn) {
  std::set<std::string> covered;
  for (const auto& n : names()) covered.insert(family_of(n));
  const auto families = model_registry().families();
  EXPECT_EQ(std::set<std::string>(families.begin(), families.end()), covered);
  EXPECT_FALSE(families.empty());
}

TEST(ModelRegistry, NamesRoundTrip) {
  for (const auto& name : names()) {
    SCOPED_TRACE(name);
    auto model = parse_model(name);
    ASSERT_TRUE(model) << model.error().describe();
    EXPECT_EQ((*model)->name(), name);
    EXPECT_EQ((*model)->family(), family_of(name));
    auto again = parse_model((*model)->name());
    ASSERT_TRUE(again);
    EXPECT_EQ((*again)->name(), name);
    EXPECT_EQ((*again)->channels(), (*model)->channels());
  }
  // The short form of Phong-1 prints in full.
  auto phong = parse_model("phong");
  ASSERT_TRUE(phong);
  EXPECT_EQ((*phong)->name(), "phong:1");
}

TEST(ModelRegistry, BadNamesAreRejectedWithTheReason) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"lambert:1", "unknown model"},
      {"", "unknown model"},
      {"Phong:1", "unknown model"},
      {"phong:0", "lobes must be 1..4 or auto"},
      {"phong:5", "lobes must be 1..4"},
      {"phong:x", "lobes must be 1..4"},
      {"phong:2:shiny", "unknown option"},
      {"sh-ls:0", "bands must be 1..10"},
      {"sh-zh:11", "bands must be 1..10"},
      {"hsh:", "not a number"},
      {"hsh", "not a number"},
      {"sh-lsop:4x", "not a number"},
  };
  for (const auto& [name, reason] : bad) {
    SCOPED_TRACE(name);
    auto model = parse_model(name);
    ASSERT_FALSE(model);
    EXPECT_EQ(model.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(model.error().message.find(reason), std::string::npos) << model.error().message;
    EXPECT_NE(model.error().message.find("\"" + name + "\""), std::string::npos) << model.error().message;
    // The accepted syntax of every family is listed.
    for (const auto& family : model_registry().families())
      EXPECT_NE(model.error().message.find(family + ":"), std::string::npos) << model.error().message;
  }
}

TEST(ModelRegistry, ChannelNamesAreUniqueAndApartFromTheQualityChannels) {
  const std::set<std::string> quality = {"rms.R", "rms.G", "rms.B",     "mpe.R",     "mpe.G",
                                         "mpe.B", "n",     "holdout.R", "holdout.G", "holdout.B"};
  for (const auto& name : names()) {
    SCOPED_TRACE(name);
    ModelPtr model = parse_model(name).value();
    if (!model->storable()) {
      // phong:auto stores once its lobe count is known.
      model = model->storable_sample();
      ASSERT_TRUE(model->storable());
      EXPECT_EQ(model->name(), name);
    }
    const auto channels = model->channels();
    ASSERT_FALSE(channels.empty());
    EXPECT_EQ(std::set<std::string>(channels.begin(), channels.end()).size(), channels.size());
    for (const auto& c : channels) EXPECT_EQ(quality.count(c), 0u) << c;
    EXPECT_EQ(model->parameter_count(), static_cast<int>(channels.size()));
  }
  // The spellings maps on disk use.
  const auto sh = parse_model("sh-ls:3").value()->channels();
  EXPECT_EQ(sh.size(), 27u);
  EXPECT_EQ(sh[5], "sh.R.05");
  EXPECT_EQ(sh[9 + 8], "sh.G.08");
  EXPECT_EQ(parse_model("hsh:2").value()->channels()[4], "hsh.G.00");
  EXPECT_EQ(parse_model("phong:2:per-lobe-m").value()->channels(),
            (std::vector<std::string>{"kd.R", "kd.G", "kd.B", "ks0.R", "ks0.G", "ks0.B", "r0.x", "r0.y", "r0.z", "m0",
                                      "ks1.R", "ks1.G", "ks1.B", "r1.x", "r1.y", "r1.z", "m1"}));
  EXPECT_EQ(parse_model("phong:auto").value()->with_attributes({{"vdrig.lobes", 1.0}}).value()->channels(),
            (std::vector<std::string>{"kd.R", "kd.G", "kd.B", "ks0.R", "ks0.G", "ks0.B", "r0.x", "r0.y", "r0.z", "m",
                                      "lobes"}));
}

TEST(ModelRegistry, EvaluateGlslAndLinearityAgreeWithTheModel) {
  const std::vector<Vec3d> dirs = {Vec3d(0, 0, 1), Vec3d(0.6, 0, 0.8), Vec3d(0, -0.6, 0.8), Vec3d(0.48, 0.36, 0.8)};
  for (const auto& name : names()) {
    SCOPED_TRACE(name);
    const ModelPtr model = storable_model(name);
    EXPECT_NE(model->glsl([](int i) { return "p" + std::to_string(i); }).find("vec3 model(ivec2 t, vec3 v)"),
              std::string::npos);
    // A map texel evaluates as the model on the texel's parameters (the float channels hold these exactly).
    std::vector<double> p(static_cast<size_t>(model->parameter_count()));
    for (size_t i = 0; i < p.size(); ++i) p[i] = 0.25 + 0.125 * static_cast<double>(i % 5);
    ParameterMap map(model, 2, 1, 10.0, 10.0);
    map.set_parameters(1, 0, p);
    EXPECT_EQ(map.parameters(1, 0), p);
    const Vec3d v = Vec3d(0.2, 0.3, 0.9).normalized();
    EXPECT_EQ(map.evaluate(1, 0, v), model->evaluate(p, v));
    MapFitOptions options;
    auto op = model->fit_operator(dirs, options);
    EXPECT_EQ(op.is_ok(), model->linear_in_shared_directions());
    if (op) {
      EXPECT_EQ(op->coeff_count() * 3, model->parameter_count());
      EXPECT_EQ(op->sample_count(), static_cast<int>(dirs.size()));
    } else {
      EXPECT_EQ(op.error().code, ErrorCode::kUnsupported);
    }
  }
}

/// Directions over the upper hemisphere, zenith up to 80 degrees.
std::vector<Vec3d> hemisphere() {
  std::vector<Vec3d> dirs;
  for (int zen = 0; zen <= 80; zen += 10)
    for (int az = 0; az < 360; az += 30) dirs.push_back(direction_from_spherical(deg_to_rad(az), deg_to_rad(zen)));
  return dirs;
}

TEST(ModelRegistry, SampleParametersAreAPlausibleTexel) {
  for (const auto& name : names()) {
    SCOPED_TRACE(name);
    const ModelPtr model = storable_model(name);
    const std::vector<double> p = model->sample_parameters(0), q = model->sample_parameters(7);
    ASSERT_EQ(static_cast<int>(p.size()), model->parameter_count());
    ASSERT_EQ(q.size(), p.size());
    EXPECT_NE(p, q);
    EXPECT_EQ(model->check_parameters(p), "");
    for (const Vec3d& v : hemisphere()) {
      const Vec3d radiance = model->evaluate(p, v);
      EXPECT_TRUE(radiance.allFinite());
      EXPECT_GT(radiance.minCoeff(), 0.01) << v.transpose();
      EXPECT_LT(radiance.maxCoeff(), 100.0) << v.transpose();
    }
  }
}

TEST(ModelRegistry, ModelsDescribeTheirTexels) {
  for (const auto& name : names()) {
    SCOPED_TRACE(name);
    const ModelPtr model = storable_model(name);
    const std::vector<double> p = model->sample_parameters(3);
    if (model->has_diffuse_part()) {
      // The direction-independent part: never more than the radiance in any direction.
      const Vec3d diffuse = model->diffuse_part(p);
      for (const Vec3d& v : hemisphere())
        EXPECT_TRUE((model->evaluate(p, v).array() >= diffuse.array() - 1e-12).all()) << v.transpose();
    }
    for (const LobeSummary& lobe : model->lobes(p)) {
      EXPECT_NEAR(lobe.direction.norm(), 1.0, 1e-9);
      EXPECT_GE(lobe.direction.z(), 0.0);
      EXPECT_GE(lobe.phong_exponent, 0.0);
    }
    // The peak direction is on the upper hemisphere and no dimmer than the normal's radiance (mean over RGB).
    const Vec3d peak = model->peak_direction(p);
    EXPECT_NEAR(peak.norm(), 1.0, 1e-9);
    EXPECT_GE(peak.z(), 0.0);
    EXPECT_GE(model->evaluate(p, peak).mean(), model->evaluate(p, Vec3d::UnitZ()).mean() - 1e-9);
    // A basis the exporters know holds its coefficients per colour.
    const ModelBasis basis = model->coefficient_basis();
    switch (basis.kind) {
      case ModelBasis::Kind::kNone:
        break;
      case ModelBasis::Kind::kSh:
      case ModelBasis::Kind::kHsh:
        EXPECT_EQ(3 * basis.bands * basis.bands, model->parameter_count());
        break;
      case ModelBasis::Kind::kPtmRgb:
        EXPECT_EQ(model->parameter_count(), 18);
        break;
      case ModelBasis::Kind::kPtmLrgb:
        EXPECT_EQ(model->parameter_count(), 9);
        break;
    }
  }
}

TEST(ModelRegistry, ModelsCheckAndFingerprintTheirOptions) {
  for (const auto& name : names()) {
    SCOPED_TRACE(name);
    MapFitOptions options;
    options.model = parse_model(name).value();
    EXPECT_TRUE(options.model->check_options(options)) << options.model->check_options(options).error().describe();
    EXPECT_EQ(options.model->options_fingerprint(options), options.model->options_fingerprint(MapFitOptions(options)));
    // The model's part is in the fit's fingerprint.
    EXPECT_NE(fit_options_fingerprint(options).find(options.model->options_fingerprint(options)), std::string::npos);
  }
  // Phong reads its own options (and the fingerprint with them); HSH does not read Phong's.
  MapFitOptions phong;
  phong.model = parse_model("phong:2").value();
  MapFitOptions relative = phong;
  relative.model_options.edit<PhongFitOptions>().residual = ResidualMode::kRelative;
  EXPECT_NE(fit_options_fingerprint(phong), fit_options_fingerprint(relative));
  relative.model = phong.model = parse_model("hsh:3").value();
  EXPECT_EQ(fit_options_fingerprint(phong), fit_options_fingerprint(relative));
  // A model refuses options it cannot fit with.
  MapFitOptions bad = phong;
  bad.model_options.edit<HshFitOptions>().smoothing = -1.0;
  EXPECT_FALSE(bad.model->check_options(bad));
  bad.model = parse_model("phong:1").value();
  bad.model_options.edit<PhongFitOptions>().max_iterations = 0;
  EXPECT_FALSE(bad.model->check_options(bad));
}

TEST(ModelRegistry, AFamilyRegisteredTwiceOrWithoutExamplesIsABrokenInvariant) {
  ModelRegistry registry;
  register_builtin_models(registry);
  EXPECT_EQ(registry.syntax(), model_registry().syntax());
  EXPECT_DEATH(register_builtin_models(registry), "registered twice");
  // A family the tests cannot reach (no example names) is refused as well.
  ModelRegistry::Entry bare;
  bare.family = "bare";
  bare.syntax = "bare";
  bare.parse = [](const std::string&) -> Result<ModelPtr> { return parse_model("phong:1"); };
  EXPECT_DEATH(registry.add(bare), "without example names");
}

/// A model that is not built in: one constant RGB radiance per texel (the mean of the observations).
class ConstantModel : public ReflectanceModel {
 public:
  std::string family() const override { return "constant"; }
  std::string name() const override { return "constant"; }
  std::vector<std::string> channels() const override { return {"c.R", "c.G", "c.B"}; }
  std::vector<double> sample_parameters(unsigned seed) const override { return {0.5, 0.4, 0.3 + 0.01 * seed}; }
  Vec3d evaluate(std::span<const double> p, const Vec3d&) const override { return Vec3d(p[0], p[1], p[2]); }
  std::string glsl(const std::function<std::string(int)>& p) const override {
    return "vec3 model(ivec2 t, vec3 v) { return vec3(" + p(0) + ", " + p(1) + ", " + p(2) + "); }\n";
  }
  Result<ParameterMap> fit_map(const MapFitContext& context) const override {
    struct Mean : TexelFitter {
      std::vector<double> fit(const TexelObservations& obs) override {
        Vec3d sum = Vec3d::Zero();
        for (const auto& r : obs.radiance) sum += r.cast<double>();
        sum /= static_cast<double>(obs.size());
        return {sum.x(), sum.y(), sum.z()};
      }
    };
    return fit_map_per_texel(shared_from_this(), context, [] { return std::make_unique<Mean>(); });
  }
};

TEST(ModelRegistry, AModelOutsideTheBuiltInsFitsThroughTheInterface) {
  ModelRegistry registry;
  registry.add({"constant",
                "constant",
                [](const std::string& settings) -> Result<ModelPtr> {
                  if (!settings.empty()) return make_error(ErrorCode::kInvalidArgument, "takes no settings");
                  return ModelPtr(std::make_shared<ConstantModel>());
                },
                {"constant"}});
  auto model = registry.parse("constant");
  ASSERT_TRUE(model) << model.error().describe();
  EXPECT_FALSE(registry.parse("constant:2"));
  EXPECT_FALSE(registry.parse("phong:1"));  // this registry holds only its own

  ObservationMapSpec spec{3, 2, 30.0, 20.0};
  ObservationMap obs(spec, 8);
  for (int t = 0; t < 2; ++t)
    for (int s = 0; s < 3; ++s)
      for (int v = 0; v < 8; ++v)
        obs.set(s, t, v, Eigen::Vector3f(0.1f * s + 0.01f * v, 0.2f * t, 0.5f), Eigen::Vector3f(0, 0, 1), kObsValid);
  MapFitOptions options;
  options.model = model.value();
  options.threads = 2;
  options.held_out = {7};
  auto map = fit_parameter_map(obs, options);
  ASSERT_TRUE(map) << map.error().describe();
  EXPECT_EQ(map->model().name(), "constant");
  EXPECT_NEAR(map->at("c.R", 2, 1), 0.2 + 0.03, 1e-6);  // mean of views 0..6
  EXPECT_NEAR(map->at("c.G", 2, 1), 0.2, 1e-6);
  EXPECT_EQ(map->at("n", 2, 1), 7.0f);
  EXPECT_NEAR(map->at("holdout.R", 2, 1), 0.04, 1e-6);  // view 7 sees 0.2 + 0.07
  options.shared_lights = true;
  auto rejected = fit_parameter_map(obs, options);
  ASSERT_FALSE(rejected);
  EXPECT_NE(rejected.error().message.find("Phong models only"), std::string::npos);
}

}  // namespace
}  // namespace vdrig::fitting

// The model registry and the ReflectanceModel interface: every built-in model name parses and prints back the same,
// bad names are rejected with the reason, channel names are unique, and a model defined outside the registry's
// built-ins (here, in the test) fits and stores a map through the same interface.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/harmonic_model.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"

namespace vdrig::fitting {
namespace {

/// Every spelling of every built-in family that the tests below go through.
const std::vector<std::string> kNames = {
    "phong:1",
    "phong:2",
    "phong:3",
    "phong:4",
    "phong:auto",
    "phong:2:per-lobe-m",
    "phong:auto:per-lobe-m",
    "ptm:rgb",
    "ptm:lrgb",
    "sh-zh:6",
    "sh-zh:1",
    "sh-lsop:6",
    "sh-ls:6",
    "sh-ls:10",
    "hsh:5",
    "hsh:1",
    "hsh:10",
};

std::string family_of(const std::string& name) { return name.substr(0, name.find(':')); }

TEST(ModelRegistry, EveryRegisteredFamilyIsCoveredHere) {
  // A family added to register_builtin_models must get names in kNames (and so the checks below).
  std::set<std::string> covered;
  for (const auto& n : kNames) covered.insert(family_of(n));
  const auto families = model_registry().families();
  EXPECT_EQ(std::set<std::string>(families.begin(), families.end()), covered);
  EXPECT_EQ(families.size(), 6u);
}

TEST(ModelRegistry, NamesRoundTrip) {
  for (const auto& name : kNames) {
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
  for (const auto& name : kNames) {
    SCOPED_TRACE(name);
    ModelPtr model = parse_model(name).value();
    if (!model->storable()) {
      // phong:auto stores once its lobe count is known.
      const auto* phong = dynamic_cast<const PhongModel*>(model.get());
      ASSERT_NE(phong, nullptr);
      model = phong->with_lobes(3);
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
  EXPECT_EQ(std::static_pointer_cast<const PhongModel>(parse_model("phong:auto").value())->with_lobes(1)->channels(),
            (std::vector<std::string>{"kd.R", "kd.G", "kd.B", "ks0.R", "ks0.G", "ks0.B", "r0.x", "r0.y", "r0.z", "m",
                                      "lobes"}));
}

TEST(ModelRegistry, EvaluateGlslAndLinearityAgreeWithTheModel) {
  const std::vector<Vec3d> dirs = {Vec3d(0, 0, 1), Vec3d(0.6, 0, 0.8), Vec3d(0, -0.6, 0.8), Vec3d(0.48, 0.36, 0.8)};
  for (const auto& name : kNames) {
    SCOPED_TRACE(name);
    ModelPtr model = parse_model(name).value();
    if (!model->storable()) model = std::static_pointer_cast<const PhongModel>(model)->with_lobes(2);
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

TEST(ModelRegistry, AFamilyRegisteredTwiceIsABrokenInvariant) {
  ModelRegistry registry;
  register_builtin_models(registry);
  EXPECT_EQ(registry.syntax(), model_registry().syntax());
  EXPECT_DEATH(register_phong_model(registry), "registered twice");
}

/// A model that is not built in: one constant RGB radiance per texel (the mean of the observations).
class ConstantModel : public ReflectanceModel {
 public:
  std::string family() const override { return "constant"; }
  std::string name() const override { return "constant"; }
  std::vector<std::string> channels() const override { return {"c.R", "c.G", "c.B"}; }
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
  registry.add({"constant", "constant", [](const std::string& settings) -> Result<ModelPtr> {
                  if (!settings.empty()) return make_error(ErrorCode::kInvalidArgument, "takes no settings");
                  return ModelPtr(std::make_shared<ConstantModel>());
                }});
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

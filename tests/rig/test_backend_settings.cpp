// A backend owns its settings (issue 24): its registration supplies the parser (BackendSpec::check) that
// `vdrig rig check` (check_rig_config) and make_rig validate its section with, so a new backend is checked with no
// edit to bring-up. Before, bringup.cpp kept its own if-chain of the hardware parsers: a backend outside it was
// "valid" whatever its section held, and make_rig left validation to the factories, one device at a time.
// Also here: the self-test's rule on move times, which a stand-in stage must satisfy through its spec.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "vdrig/core/settings.hpp"
#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/test/instant_stage.hpp"

namespace vdrig::rig {
namespace {
using nlohmann::json;

std::string joined(const std::vector<std::string>& problems) {
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  return all;
}

/// A stage that stands wherever it is told, at once, with the speed profile it is given.
std::unique_ptr<PanTiltStage> instant_stage(const StageSpec& spec) {
  return std::make_unique<test::InstantStage>("test-stage", spec);
}

/// A camera whose picture brightens with the exposure (so the self-test's bracket passes).
class RampCamera final : public Camera {
 public:
  std::string backend() const override { return "test-camera"; }
  Result<CameraInfo> info() override { return CameraInfo{"ramp", 8, 8, 8, 1e-5, 10.0, false}; }
  Status set_exposure(double exposure_s, double) override {
    exposure_s_ = exposure_s;
    return Status::ok();
  }
  Result<Frame> capture() override {
    Frame f;
    f.image = cv::Mat(8, 8, CV_8UC3, cv::Scalar::all(std::min(255.0, 4000.0 * exposure_s_)));
    f.exposure_s = exposure_s_;
    return f;
  }

 private:
  double exposure_s_ = 0.001;
};

/// The settings of the test-only "test-stage" backend: "speed_deg_s" (30, in (0, 1000]), "port" (required,
/// 1..65535), nothing else.
struct TestStageConfig {
  double speed_deg_s = 30.0;
  int port = 0;
  static Result<TestStageConfig> parse(const json& section) {
    Settings s(section, "stage test-stage", {"backend"});
    TestStageConfig c;
    c.speed_deg_s = s.number("speed_deg_s", 30.0, 1e-3, 1000.0);
    c.port = static_cast<int>(s.required_integer("port", 1, 65535));
    s.reject_unknown({"speed_deg_s", "port"});
    if (!s.is_valid(nullptr)) return s.error();
    return c;
  }
  json effective() const { return {{"backend", "test-stage"}, {"speed_deg_s", speed_deg_s}, {"port", port}}; }
};

/// A registry with the test stage (counting the devices its factory builds), a test camera and a test light whose
/// parser takes only {"backend"}.
struct TestBackends {
  int stages_built = 0;
  BackendRegistry registry;
  TestBackends() {
    registry.add_stage("test-stage",
                       [this](const json& section, RigContext&) -> Result<std::unique_ptr<PanTiltStage>> {
                         auto config = TestStageConfig::parse(section);
                         if (!config) return config.error();
                         ++stages_built;
                         return instant_stage(StageSpec{});
                       },
                       {.check = settings_check(TestStageConfig::parse)});
    registry.add_camera("test-camera",
                        [](const json&, RigContext&) -> Result<std::unique_ptr<Camera>> {
                          return std::unique_ptr<Camera>(std::make_unique<RampCamera>());
                        },
                        {.check = [](const json& section) -> Result<json> {
                          Settings s(section, "camera test-camera", {"backend"});
                          s.reject_unknown(std::vector<std::string>{});
                          if (!s.is_valid(nullptr)) return s.error();
                          return section;
                        }});
  }
};

TEST(BackendSettings, RigCheckReportsEveryProblemOfANewBackendsSection) {
  TestBackends t;
  // Three problems: "port" missing, "speed_deg_s" out of range, an unknown key.
  const json config = {{"stage", {{"backend", "test-stage"}, {"speed_deg_s", -5}, {"sped_deg_s", 10}}},
                       {"camera", {{"backend", "test-camera"}}}};
  const auto check = check_rig_config(config, t.registry);
  const std::string all = joined(check.problems);
  for (const char* key : {"\"port\"", "\"speed_deg_s\"", "\"sped_deg_s\""})
    EXPECT_NE(all.find(key), std::string::npos) << key << " not reported:\n" << all;

  const json good = {{"stage", {{"backend", "test-stage"}, {"port", 5020}}}, {"camera", {{"backend", "test-camera"}}}};
  const auto ok = check_rig_config(good, t.registry);
  EXPECT_TRUE(ok.problems.empty()) << joined(ok.problems);
  // The effective settings are the backend's own, defaults filled in.
  EXPECT_EQ(ok.effective["stage"], json({{"backend", "test-stage"}, {"speed_deg_s", 30.0}, {"port", 5020}}));
}

TEST(BackendSettings, MakeRigValidatesEverySectionBeforeBuildingAnyDevice) {
  TestBackends t;
  // A good stage with a bad camera section: nothing may be built (a real stage would have been opened and homed).
  const json config = {{"stage", {{"backend", "test-stage"}, {"port", 5020}}},
                       {"camera", {{"backend", "test-camera"}, {"exposure_s", 0.1}}}};
  auto rig = t.registry.make_rig(config);
  ASSERT_FALSE(rig) << "built a rig from a camera section with an unknown key";
  EXPECT_EQ(rig.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(rig.error().message.find("\"exposure_s\""), std::string::npos) << rig.error().message;
  EXPECT_EQ(t.stages_built, 0) << "the stage was built before the camera's section was found bad";

  // Every section's problems at once.
  const json both_bad = {{"stage", {{"backend", "test-stage"}}}, {"camera", {{"backend", "test-camera"}, {"x", 1}}}};
  rig = t.registry.make_rig(both_bad);
  ASSERT_FALSE(rig);
  EXPECT_NE(rig.error().message.find("\"port\""), std::string::npos) << rig.error().message;
  EXPECT_NE(rig.error().message.find("\"x\""), std::string::npos) << rig.error().message;

  const json good = {{"stage", {{"backend", "test-stage"}, {"port", 5020}}}, {"camera", {{"backend", "test-camera"}}}};
  ASSERT_TRUE(t.registry.make_rig(good));
  EXPECT_EQ(t.stages_built, 1);
}

TEST(BackendSettings, TheRegistrationDecidesEvenForANameRigKnows) {
  // Bring-up has no list of its own: a backend registered as "gpio-stepdir" is checked by the parser it was
  // registered with, not by the built-in step/dir parser.
  BackendRegistry registry;
  registry.add_stage("gpio-stepdir",
                     [](const json&, RigContext&) -> Result<std::unique_ptr<PanTiltStage>> {
                       return make_error(ErrorCode::kUnsupported, "not built in this test");
                     },
                     {.check = [](const json&) -> Result<json> {
                       return make_error(ErrorCode::kInvalidArgument, "stage gpio-stepdir: the registered parser ran");
                     }});
  registry.add_camera(
      "none", [](const json&, RigContext&) -> Result<std::unique_ptr<Camera>> { return std::unique_ptr<Camera>(); },
      {.check = [](const json& section) -> Result<json> { return section; }});
  const json config = {{"stage", {{"backend", "gpio-stepdir"}, {"chip", "gpiochip0"}}},
                       {"camera", {{"backend", "none"}}}};
  const auto check = check_rig_config(config, registry);
  EXPECT_NE(joined(check.problems).find("the registered parser ran"), std::string::npos) << joined(check.problems);
}

TEST(BackendSettings, EveryHardwareBackendIsRegisteredWithItsParser) {
  BackendRegistry registry;
  register_hardware_backends(registry);
  const std::pair<const char*, std::vector<std::string>> kinds[] = {{"stage", registry.stage_backends()},
                                                                    {"camera", registry.camera_backends()},
                                                                    {"light", registry.light_backends()}};
  for (const auto& [kind, names] : kinds)
    for (const auto& name : names) {
      // Checked without a device: an unknown key is named, whatever else the section lacks.
      auto checked = registry.check_device_section(kind, name, {{"backend", name}, {"no_such_setting", 1}});
      ASSERT_TRUE(checked) << kind << " " << name << " has no settings parser";
      ASSERT_FALSE(*checked) << kind << " " << name << " accepted an unknown key";
      EXPECT_NE(checked->error().message.find("no_such_setting"), std::string::npos)
          << kind << " " << name << ": " << checked->error().message;
    }
}

TEST(BackendSettingsDeathTest, ARegistrationWithoutAParserIsRefused) {
  BackendRegistry registry;
  EXPECT_DEATH(registry.add_stage("no-parser",
                                  [](const json&, RigContext&) -> Result<std::unique_ptr<PanTiltStage>> {
                                    return std::unique_ptr<PanTiltStage>();
                                  },
                                  {}),
               "no-parser");
}

TEST(SelfTest, AnInstantStagePassesOnlyWhenItsSpecSaysItIsFast) {
  // The self-test times each move against the profile of the stage's spec: a move much faster than the profile
  // means the drive did not get the speeds sent. A stand-in stage that moves at once must say so in its spec.
  AxisSpec slow_axis{-3.2, 3.2, 0.5, 1.0, false};  // 29 deg/s: a 5 deg move takes ~0.4 s
  Rig slow{instant_stage(StageSpec{slow_axis, slow_axis}), std::make_unique<RampCamera>(), nullptr};
  auto steps = run_self_test(slow);
  const auto failed = std::find_if(steps.begin(), steps.end(), [](const SelfTestStep& s) { return !s.passed; });
  ASSERT_NE(failed, steps.end()) << "an instant stage passed against a 29 deg/s profile";
  EXPECT_EQ(failed->name, "move pan");
  EXPECT_NE(failed->detail.find("much faster than the configured profile"), std::string::npos) << failed->detail;

  AxisSpec fast_axis{-3.2, 3.2, 1e6, 1e9, false};
  Rig fast{instant_stage(StageSpec{fast_axis, fast_axis}), std::make_unique<RampCamera>(), nullptr};
  steps = run_self_test(fast);
  for (const auto& s : steps) EXPECT_TRUE(s.passed) << s.name << ": " << s.detail;
}

}  // namespace
}  // namespace vdrig::rig

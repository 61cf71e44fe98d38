// The top level of a rig config is validated like every section (issue 23): a misspelt "geomtry", "ligth" or
// "simm" used to pass `vdrig rig check` and make_rig, and the capture then ran with an ideal geometry, no light and
// the default scene; "lock": 5 was ignored, and so were unknown keys in the simulator's device sections. Every
// problem is reported at once, each naming its key; the configs that were valid stay valid.
#include <gtest/gtest.h>

#include "test_support.hpp"
#include "vdrig/rig/bringup.hpp"

namespace vdrig::capture {
namespace {
using nlohmann::json;

rig::BackendRegistry full_registry() { return sim::simulator_and_hardware_backends(); }

std::string joined(const std::vector<std::string>& problems) {
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  return all;
}

TEST(RigConfigTopLevel, MisspeltKeysAreProblemsForCheckAndMakeRig) {
  const auto registry = full_registry();
  json config = testing::small_sim_config();
  config["geomtry"] = {{"distance_mm", 2000}};
  config["ligth"] = {{"backend", "sim"}};
  config["simm"] = {{"scene", "checkerboard"}};
  const auto check = rig::check_rig_config(config, registry);
  for (const char* key : {"\"geomtry\"", "\"ligth\"", "\"simm\""})
    EXPECT_NE(joined(check.problems).find(key), std::string::npos) << key << " not reported:\n"
                                                                   << joined(check.problems);
  auto rig = registry.make_rig(config);
  ASSERT_FALSE(rig) << "a rig was built from a config with misspelt keys";
  EXPECT_EQ(rig.error().code, ErrorCode::kInvalidArgument);
  for (const char* key : {"\"geomtry\"", "\"ligth\"", "\"simm\""})
    EXPECT_NE(rig.error().message.find(key), std::string::npos) << key << " not in: " << rig.error().message;
}

TEST(RigConfigTopLevel, LockMustBeANonEmptyString) {
  const auto registry = full_registry();
  for (const json& lock : {json(5), json(""), json::array({"bench"})}) {
    json config = testing::small_sim_config();
    config["lock"] = lock;
    const auto check = rig::check_rig_config(config, registry);
    EXPECT_NE(joined(check.problems).find("\"lock\""), std::string::npos)
        << lock.dump() << ": " << joined(check.problems);
    EXPECT_FALSE(registry.make_rig(config)) << "\"lock\": " << lock.dump() << " was ignored";
  }
  json named = testing::small_sim_config();
  named["lock"] = "bench-1";
  EXPECT_TRUE(rig::check_rig_config(named, registry).problems.empty());
}

TEST(RigConfigTopLevel, SimulatedDeviceSectionsHoldOnlyTheirBackend) {
  const auto registry = full_registry();
  json config = testing::small_sim_config();
  config["stage"]["speed_deg_s"] = 10;  // belongs in "sim"."stage"
  config["light"]["on"] = true;
  const auto check = rig::check_rig_config(config, registry);
  for (const char* key : {"\"speed_deg_s\"", "\"on\""})
    EXPECT_NE(joined(check.problems).find(key), std::string::npos) << key << " not reported:\n"
                                                                   << joined(check.problems);
  auto rig = registry.make_rig(config);
  ASSERT_FALSE(rig) << "unknown keys of the sim stage and light were ignored";
  EXPECT_NE(rig.error().message.find("\"speed_deg_s\""), std::string::npos) << rig.error().message;
}

TEST(RigConfigTopLevel, EveryProblemAtOnceWithItsKeyPath) {
  const auto registry = full_registry();
  json config = testing::small_sim_config();
  config["geomtry"] = json::object();
  config["lock"] = 5;
  config["sim"]["stage"]["spede_deg_s"] = 10;
  config["geometry"] = {{"distance_mm", -1}};
  const auto check = rig::check_rig_config(config, registry);
  const std::string all = joined(check.problems);
  for (const char* named : {"\"geomtry\"", "\"lock\"", "spede_deg_s", "distance_mm"})
    EXPECT_NE(all.find(named), std::string::npos) << named << " not reported:\n" << all;
}

TEST(RigConfigTopLevel, ASharedSectionNoDeviceReadsIsAProblem) {
  const auto registry = full_registry();
  json config = {{"stage", {{"backend", "gpio-stepdir"}}},
                 {"camera", {{"backend", "v4l2"}, {"device", "/dev/video0"}}},
                 {"sim", {{"scene", "checkerboard"}}}};
  const auto check = rig::check_rig_config(config, registry);
  EXPECT_NE(joined(check.problems).find("\"sim\" is read only by"), std::string::npos) << joined(check.problems);
}

TEST(RigConfigTopLevel, ValidConfigsStayValid) {
  const auto registry = full_registry();
  json config = testing::small_sim_config();
  config["geometry"] = {{"distance_mm", 2500}, {"source", "tape measure"}};
  config["lock"] = "bench-1";
  const auto check = rig::check_rig_config(config, registry);
  EXPECT_TRUE(check.problems.empty()) << joined(check.problems);
  EXPECT_TRUE(registry.make_rig(config));
  EXPECT_TRUE(registry.make_rig(sim::sim_rig_config()));
}

}  // namespace
}  // namespace vdrig::capture

// A rig config as `vdrig rig check` and make_rig read it: the text (parse_json_text, every repeated key reported),
// the top level (BackendRegistry::top_level_problems: unknown keys, "lock", "geometry", the shared "sim" section),
// check_rig_config (each device section through its backend's settings parser, BackendSpec::check), and make_rig,
// whose factories here parse their settings and stop: no device is opened. Invariants:
//  - a text with a repeated key is refused by parse_json_strict (what read_json_file uses);
//  - every top-level problem is among check_rig_config's problems;
//  - a config check_rig_config accepts is not refused by make_rig as invalid (it gets as far as a factory);
//  - an accepted config round-trips: dumped and parsed again it is the same value, and still accepted.
#include <algorithm>

#include "fuzz_support.hpp"
#include "vdrig/core/json_text.hpp"
#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/sim_rig.hpp"

using namespace vdrig;
using nlohmann::json;

namespace {

/// A factory that validates its section with the backend's own settings parser and then declines (nothing to
/// build in a fuzzer).
template <typename Device>
rig::Factory<Device> parse_only(const rig::BackendSpec& spec) {
  return [check = spec.check](const json& settings, rig::RigContext&) -> Result<std::unique_ptr<Device>> {
    auto parsed = check(settings);
    if (!parsed) return parsed.error();
    return make_error(ErrorCode::kUnsupported, "fuzz: parsed only");
  };
}

/// The registry as sim::register_backends and register_hardware_backends make it, every factory replaced by a
/// parse-only one: each backend's declarations (its sections, its settings parser) are its own.
rig::BackendRegistry make_registry() {
  rig::BackendRegistry real;
  sim::register_backends(real);
  rig::register_hardware_backends(real);
  rig::BackendRegistry r;
  sim::register_backends(r);  // the shared "sim" section; the device factories are replaced below
  for (const auto& name : real.stage_backends()) {
    const rig::BackendSpec& spec = *real.spec_of("stage", name);
    r.add_stage(name, parse_only<rig::PanTiltStage>(spec), spec);
  }
  for (const auto& name : real.camera_backends()) {
    const rig::BackendSpec& spec = *real.spec_of("camera", name);
    r.add_camera(name, parse_only<rig::Camera>(spec), spec);
  }
  for (const auto& name : real.light_backends()) {
    const rig::BackendSpec& spec = *real.spec_of("light", name);
    r.add_light(name, parse_only<rig::Light>(spec), spec);
  }
  return r;
}

void require(bool holds) {
  if (!holds) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const rig::BackendRegistry registry = [] {
    (void)fuzz::scratch_dir();  // quiet logs
    return make_registry();
  }();
  const std::string text = fuzz::as_string(data, size);
  auto parsed = parse_json_text(text, "fuzz");
  if (!parsed) return 0;
  if (!parsed->duplicate_keys.empty()) require(!parse_json_strict(text, "fuzz"));
  const json& config = parsed->value;

  const auto check = rig::check_rig_config(config, registry);
  for (const auto& problem : registry.top_level_problems(config))
    require(std::find(check.problems.begin(), check.problems.end(), problem) != check.problems.end());
  auto rig = registry.make_rig(config);
  // The sim section on its own, as the simulator reads it whatever the backends say.
  if (config.is_object()) (void)sim::SimConfig::from_json(config.value("sim", json::object()));
  if (!check.problems.empty() || !parsed->duplicate_keys.empty()) return 0;

  require(!rig && rig.error().code != ErrorCode::kInvalidArgument);
  auto again = parse_json_strict(config.dump(), "fuzz round trip");
  require(again && again.value() == config);
  require(rig::check_rig_config(again.value(), registry).problems.empty());
  return 0;
}

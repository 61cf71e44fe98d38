// A rig config as `vdrig rig check` and make_rig read it: the text (parse_json_text, every repeated key reported),
// the top level (BackendRegistry::top_level_problems: unknown keys, "lock", "geometry", the shared "sim" section),
// check_rig_config (each device section through the hardware backends' parse() or the backend's declared check),
// and make_rig, whose factories here parse their settings and stop: no device is opened. Invariants:
//  - a text with a repeated key is refused by parse_json_strict (what read_json_file uses);
//  - every top-level problem is among check_rig_config's problems;
//  - a config check_rig_config accepts is not refused by make_rig as invalid (it gets as far as a factory);
//  - an accepted config round-trips: dumped and parsed again it is the same value, and still accepted.
#include <algorithm>

#include "fuzz_support.hpp"
#include "stepdir_stage.hpp"
#include "vdrig/core/json_text.hpp"
#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/sim_rig.hpp"
#if VDRIG_HAVE_MODBUS
#include "modbus_stage.hpp"
#endif
#if VDRIG_HAVE_V4L2
#include "v4l2_camera.hpp"
#endif
#if VDRIG_HAVE_USB
#include "usb_ptp_camera.hpp"
#endif

using namespace vdrig;
using nlohmann::json;

namespace {

/// A factory that parses its settings with `parse` and then declines (nothing to build in a fuzzer).
template <typename Device, typename Parse>
rig::Factory<Device> parse_only(Parse parse) {
  return [parse](const json& settings, rig::RigContext& ctx) -> Result<std::unique_ptr<Device>> {
    auto parsed = parse(settings, ctx);
    if (!parsed) return parsed.error();
    return make_error(ErrorCode::kUnsupported, "fuzz: parsed only");
  };
}

/// The registry as sim::register_backends and the hardware backends make it, with parse-only factories: the
/// simulator's declarations (its "sim" section, its device sections' check) are its own.
rig::BackendRegistry make_registry() {
  rig::BackendRegistry r;
  sim::register_backends(r);  // the shared "sim" section; the sim factories are replaced below
  const auto sim = [](const json&, rig::RigContext& ctx) {
    return sim::SimConfig::from_json(ctx.config.value("sim", json::object()));
  };
  r.add_stage("sim", parse_only<rig::PanTiltStage>(sim), sim::backend_spec("stage"));
  r.add_camera("sim", parse_only<rig::Camera>(sim), sim::backend_spec("camera"));
  r.add_light("sim", parse_only<rig::Light>(sim), sim::backend_spec("light"));
  r.add_stage("gpio-stepdir", parse_only<rig::PanTiltStage>(
                                  [](const json& s, rig::RigContext&) { return rig::StepDirStageConfig::parse(s); }));
#if VDRIG_HAVE_MODBUS
  r.add_stage("modbus-rtu", parse_only<rig::PanTiltStage>([](const json& s, rig::RigContext&) {
                return rig::ModbusStageConfig::parse(s, true);
              }));
  r.add_stage("modbus-tcp", parse_only<rig::PanTiltStage>([](const json& s, rig::RigContext&) {
                return rig::ModbusStageConfig::parse(s, false);
              }));
#endif
#if VDRIG_HAVE_V4L2
  r.add_camera(
      "v4l2", parse_only<rig::Camera>([](const json& s, rig::RigContext&) { return rig::V4l2CameraConfig::parse(s); }));
#endif
#if VDRIG_HAVE_USB
  r.add_camera("usb-ptp",
               parse_only<rig::Camera>([](const json& s, rig::RigContext&) { return rig::UsbPtpConfig::parse(s); }));
#endif
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

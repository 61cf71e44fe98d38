// A rig config through the backend registry (the dispatch on "stage"/"camera"/"light" sections) to each backend's
// settings parser: the simulator's SimConfig::from_json and the hardware backends' parse(). No device is opened:
// the factories stop after parsing.
#include "fuzz_support.hpp"
#include "stepdir_stage.hpp"
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

rig::BackendRegistry make_registry() {
  rig::BackendRegistry r;
  const auto sim = [](const json&, rig::RigContext& ctx) {
    return sim::SimConfig::from_json(ctx.config.value("sim", json::object()));
  };
  r.add_stage("sim", parse_only<rig::PanTiltStage>(sim));
  r.add_camera("sim", parse_only<rig::Camera>(sim));
  r.add_light("sim", parse_only<rig::Light>(sim));
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const rig::BackendRegistry registry = [] {
    (void)fuzz::scratch_dir();  // quiet logs
    return make_registry();
  }();
  const json config = json::parse(data, data + size, nullptr, false);
  if (config.is_discarded()) return 0;
  (void)registry.make_rig(config);
  // The sim section on its own, as the simulator reads it whatever the backends say.
  if (config.is_object()) (void)sim::SimConfig::from_json(config.value("sim", json::object()));
  return 0;
}

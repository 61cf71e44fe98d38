// Backends are created by name from a JSON rig config through a registry. Registration is explicit
// (register_hardware_backends, sim::register_backends): static registrar objects would vanish when linking static
// libraries. docs/rig-backends.md says how to add a backend.
//
// Rig config (JSON; angles in degrees, lengths in mm, times in seconds):
//   { "stage":  { "backend": "modbus-tcp", ... backend settings ... },
//     "camera": { "backend": "v4l2", ... },
//     "light":  { "backend": "gpio", ... },           (optional)
//     ...      sections shared by backends, e.g. "sim": { "scene": "patchwork", ... } }
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

/// Passed to every factory while one rig is built: the whole config, and a place where backends that must share
/// state (the simulator's stage and camera share one world) keep it.
struct RigContext {
  nlohmann::json config;
  std::map<std::string, std::shared_ptr<void>> shared;
};

template <typename Device>
using Factory = std::function<Result<std::unique_ptr<Device>>(const nlohmann::json& settings, RigContext& ctx)>;

class BackendRegistry {
 public:
  void add_stage(const std::string& name, Factory<PanTiltStage> factory);
  void add_camera(const std::string& name, Factory<Camera> factory);
  void add_light(const std::string& name, Factory<Light> factory);

  std::vector<std::string> stage_backends() const;
  std::vector<std::string> camera_backends() const;
  std::vector<std::string> light_backends() const;

  /// Builds every device of the config. An unknown backend name is kInvalidArgument listing the known ones.
  Result<Rig> make_rig(const nlohmann::json& config) const;

 private:
  std::map<std::string, Factory<PanTiltStage>> stages_;
  std::map<std::string, Factory<Camera>> cameras_;
  std::map<std::string, Factory<Light>> lights_;
};

/// Registers the hardware backends compiled into this build (modbus-rtu, modbus-tcp, gpio-stepdir, v4l2,
/// libcamera, gpio light, ...). Backends whose library was absent at build time are not registered.
void register_hardware_backends(BackendRegistry& registry);

}  // namespace vdrig::rig

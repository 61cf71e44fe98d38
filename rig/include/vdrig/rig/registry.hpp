// Backends are created by name from a JSON rig config through a registry; each registration supplies the backend's
// factory and its settings parser (BackendSpec). Registration is explicit
// (register_hardware_backends, sim::register_backends): static registrar objects would vanish when linking static
// libraries. docs/rig-backends.md says how to add a backend.
//
// Rig config (JSON; angles in degrees, lengths in mm, times in seconds):
//   { "stage":  { "backend": "modbus-tcp", ... backend settings ... },
//     "camera": { "backend": "v4l2", ... },
//     "light":  { "backend": "gpio", ... },           (optional)
//     "geometry": { ... },                            (optional, geometry_config.hpp)
//     "lock": "bench-1",                              (optional, capture/process_lock.hpp)
//     ...      sections shared by backends, e.g. "sim": { "scene": "patchwork", ... } }
// The top level is validated like every section: a key that is none of these, nor a section a backend of the
// registry declares, is an error (a misspelt "geomtry" would otherwise mean an ideal geometry).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
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

/// What a backend reads of a rig config besides building its device, declared when it is registered, so that a
/// whole config is validated (`vdrig rig check`, make_rig) before any device is opened.
struct BackendSpec {
  /// Top-level sections the backend reads besides its own device section (the simulator's "sim"); each is
  /// registered with add_section. A config may have such a section only when one of its devices reads it.
  std::vector<std::string> sections = {};  // (defaulted, so `{.check = ...}` says all a backend without any needs)
  /// Required: the backend's settings parser. Validates the device section ("backend" included) without opening
  /// the device and returns the settings as the backend will use them (defaults filled in; `vdrig rig check`
  /// prints them), or kInvalidArgument naming every problem. make_rig runs it on every device section before it
  /// calls any factory. settings_check() makes one from a `Config::parse` and `Config::effective`.
  std::function<Result<nlohmann::json>(const nlohmann::json& section)> check;
};

/// A BackendSpec::check from a settings parser: `parse(section)` returns Result<Config> (kInvalidArgument naming
/// every problem) and `Config::effective()` the settings as the backend uses them, in JSON.
template <typename Parse>
std::function<Result<nlohmann::json>(const nlohmann::json&)> settings_check(Parse parse) {
  return [parse](const nlohmann::json& section) -> Result<nlohmann::json> {
    auto config = parse(section);
    if (!config) return config.error();
    return config.value().effective();
  };
}

class BackendRegistry {
 public:
  /// A backend: its factory (which opens the device) and its BackendSpec, whose `check` is required (a registration
  /// without one is a VDRIG_CHECK failure: `vdrig rig check` could not validate the section).
  void add_stage(const std::string& name, Factory<PanTiltStage> factory, BackendSpec spec);
  void add_camera(const std::string& name, Factory<Camera> factory, BackendSpec spec);
  void add_light(const std::string& name, Factory<Light> factory, BackendSpec spec);
  /// A top-level section shared by backends (the simulator's "sim") and how to validate it without a device.
  void add_section(const std::string& name, std::function<Status(const nlohmann::json& section)> check);

  std::vector<std::string> stage_backends() const;
  std::vector<std::string> camera_backends() const;
  std::vector<std::string> light_backends() const;

  /// Every problem of the config's top level, each naming its key: a key that is neither one of the config's own
  /// ("stage", "camera", "light", "geometry", "lock") nor a section declared by a backend; a declared section that
  /// no backend of this config reads; a "lock" that is not a non-empty string; the problems of "geometry" and of
  /// each shared section. The device sections are left to device_section_problems and the factories.
  std::vector<std::string> top_level_problems(const nlohmann::json& config) const;
  /// The result of the backend's BackendSpec::check for a device section of `kind` ("stage", "camera", "light"),
  /// or nullopt when `backend` is not registered for that kind.
  std::optional<Result<nlohmann::json>> check_device_section(const std::string& kind, const std::string& backend,
                                                             const nlohmann::json& section) const;
  /// The BackendSpec `backend` was registered with for `kind`, or null when it is not registered.
  const BackendSpec* spec_of(const std::string& kind, const std::string& backend) const;

  /// Validates the whole config before any device is opened: the top level (top_level_problems) and each device
  /// section through its backend's BackendSpec::check (kInvalidArgument naming every problem of every section);
  /// then builds every device. An unknown backend name is kInvalidArgument listing the known ones.
  Result<Rig> make_rig(const nlohmann::json& config) const;

 private:
  template <typename Device>
  struct Entry {
    Factory<Device> factory;
    BackendSpec spec;
  };

  std::map<std::string, Entry<PanTiltStage>> stages_;
  std::map<std::string, Entry<Camera>> cameras_;
  std::map<std::string, Entry<Light>> lights_;
  std::map<std::string, std::function<Status(const nlohmann::json&)>> sections_;
};

/// Registers the hardware backends compiled into this build (modbus-rtu, modbus-tcp, gpio-stepdir, v4l2,
/// libcamera, gpio light, ...), each with its settings parser. Backends whose library was absent at build time are
/// not registered. The list is rig/src/backend_list.cpp.
void register_hardware_backends(BackendRegistry& registry);

}  // namespace vdrig::rig

// "gpio" light: one output line switches the light (through a relay or a MOSFET driver).
// Settings: "chip" ("gpiochip0"), "line" (offset, required), "active_low" (false). The light starts off.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "gpiod_lines.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

struct GpioLightConfig {
  std::string chip = "gpiochip0";
  int line = -1;
  bool active_low = false;
  /// Validates every key up front (kInvalidArgument listing each problem).
  static Result<GpioLightConfig> parse(const nlohmann::json& settings);
  /// The settings as used, defaults filled in (`vdrig rig check`).
  nlohmann::json effective() const;
};

class GpioLight final : public Light {
 public:
  static Result<std::unique_ptr<Light>> create(const GpioLightConfig& config);
  std::string backend() const override { return "gpio"; }
  Status set_on(bool on) override;

 private:
  explicit GpioLight(std::unique_ptr<GpioLine> line) : line_(std::move(line)) {}
  std::unique_ptr<GpioLine> line_;
};

}  // namespace vdrig::rig

// "gpio" light: one output line switches the light (through a relay or a MOSFET driver).
// Settings: "chip" ("gpiochip0"), "line" (offset, required), "active_low" (false). The light starts off.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>

#include "gpiod_lines.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

class GpioLight final : public Light {
 public:
  static Result<std::unique_ptr<Light>> create(const nlohmann::json& settings);
  std::string backend() const override { return "gpio"; }
  Status set_on(bool on) override;

 private:
  explicit GpioLight(std::unique_ptr<GpioLine> line) : line_(std::move(line)) {}
  std::unique_ptr<GpioLine> line_;
};

}  // namespace vdrig::rig

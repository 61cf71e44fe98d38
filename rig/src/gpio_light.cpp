#include "gpio_light.hpp"

#include "vdrig/core/settings.hpp"

namespace vdrig::rig {

Result<std::unique_ptr<Light>> GpioLight::create(const nlohmann::json& settings) {
  Settings s(settings, "light gpio", {"backend"});
  const std::string chip_name = s.string("chip", "gpiochip0");
  const int offset = static_cast<int>(s.required_integer("line", 0, 4095));
  const bool active_low = s.boolean("active_low", false);
  s.reject_unknown({"chip", "line", "active_low"});
  if (!s.is_valid(nullptr)) return s.error();
  auto chip = GpioChip::open(chip_name);
  if (!chip) return chip.error();
  auto line = GpioLine::output(chip.value(), offset, "vdrig-light", active_low, false);
  if (!line) return line.error();
  return std::unique_ptr<Light>(new GpioLight(std::move(line.value())));
}

Status GpioLight::set_on(bool on) { return line_->set(on); }

}  // namespace vdrig::rig

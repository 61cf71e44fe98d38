#include "gpio_light.hpp"

#include "vdrig/core/settings.hpp"

namespace vdrig::rig {

Result<GpioLightConfig> GpioLightConfig::parse(const nlohmann::json& settings) {
  Settings s(settings, "light gpio", {"backend"});
  GpioLightConfig c;
  c.chip = s.string("chip", "gpiochip0");
  c.line = static_cast<int>(s.required_integer("line", 0, 4095));
  c.active_low = s.boolean("active_low", false);
  s.reject_unknown({"chip", "line", "active_low"});
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

nlohmann::json GpioLightConfig::effective() const {
  return {{"backend", "gpio"}, {"chip", chip}, {"line", line}, {"active_low", active_low}};
}

Result<std::unique_ptr<Light>> GpioLight::create(const GpioLightConfig& config) {
  auto chip = GpioChip::open(config.chip);
  if (!chip) return chip.error();
  auto line = GpioLine::output(chip.value(), config.line, "vdrig-light", config.active_low, false);
  if (!line) return line.error();
  return std::unique_ptr<Light>(new GpioLight(std::move(line.value())));
}

Status GpioLight::set_on(bool on) { return line_->set(on); }

}  // namespace vdrig::rig

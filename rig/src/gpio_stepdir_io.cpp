// The libgpiod side of the gpio-stepdir stage (StepDirAxisIo over GpioLines) and the registration of the gpiod
// backends (stage gpio-stepdir, light gpio).
#include <time.h>

#include "backends.hpp"
#include "gpio_light.hpp"
#include "gpiod_lines.hpp"
#include "stepdir_stage.hpp"

namespace vdrig::rig {
namespace {

class GpiodAxisIo final : public StepDirAxisIo {
 public:
  static Result<std::unique_ptr<StepDirAxisIo>> open(const std::shared_ptr<GpioChip>& chip, const StepDirAxisConfig& c,
                                                     double pulse_s, const char* name) {
    auto io = std::unique_ptr<GpiodAxisIo>(new GpiodAxisIo(c, pulse_s));
    const std::string consumer = std::string("vdrig-") + name;
    auto step = GpioLine::output(chip, c.step_line, consumer + "-step", false, false);
    if (!step) return step.error();
    io->step_ = std::move(step.value());
    auto dir = GpioLine::output(chip, c.dir_line, consumer + "-dir", false, false);
    if (!dir) return dir.error();
    io->dir_ = std::move(dir.value());
    auto limit = GpioLine::input(chip, c.limit_line, consumer + "-limit", c.limit_active_low, c.limit_active_low);
    if (!limit) return limit.error();
    io->limit_ = std::move(limit.value());
    if (c.enable_line >= 0) {
      // Requested disabled: the driver is enabled on the first move, not the moment the rig config is loaded.
      auto en = GpioLine::output(chip, c.enable_line, consumer + "-enable", c.enable_active_low, false);
      if (!en) return en.error();
      io->enable_ = std::move(en.value());
    }
    return std::unique_ptr<StepDirAxisIo>(std::move(io));
  }

  Status set_enable(bool on) override { return enable_ ? enable_->set(on) : Status::ok(); }
  Status set_direction(bool positive) override { return dir_->set(positive != c_.dir_invert); }
  Status pulse() override {
    VDRIG_TRY(step_->set(true));
    // Busy-wait the pulse width: a few microseconds are below what a sleep can resolve.
    timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    do {
      clock_gettime(CLOCK_MONOTONIC, &t);
    } while ((t.tv_sec - t0.tv_sec) * 1e9 + (t.tv_nsec - t0.tv_nsec) < pulse_s_ * 1e9);
    return step_->set(false);
  }
  Result<bool> limit_active() override { return limit_->get(); }

 private:
  GpiodAxisIo(const StepDirAxisConfig& c, double pulse_s) : c_(c), pulse_s_(pulse_s) {}
  StepDirAxisConfig c_;
  double pulse_s_;
  std::unique_ptr<GpioLine> step_, dir_, limit_, enable_;
};

class GpiodInput final : public StepDirInput {
 public:
  explicit GpiodInput(std::unique_ptr<GpioLine> line) : line_(std::move(line)) {}
  Result<bool> active() override { return line_->get(); }

 private:
  std::unique_ptr<GpioLine> line_;
};

}  // namespace

void register_gpiod_backends(BackendRegistry& registry) {
  registry.add_stage(
      "gpio-stepdir",
      [](const nlohmann::json& settings, RigContext&) -> Result<std::unique_ptr<PanTiltStage>> {
        auto config = StepDirStageConfig::parse(settings);
        if (!config) return config.error();
        auto chip = GpioChip::open(config->chip);
        if (!chip) return chip.error();
        auto pan = GpiodAxisIo::open(chip.value(), config->pan, config->step_pulse_s, "pan");
        if (!pan) return pan.error();
        auto tilt = GpiodAxisIo::open(chip.value(), config->tilt, config->step_pulse_s, "tilt");
        if (!tilt) return tilt.error();
        std::unique_ptr<StepDirInput> estop;
        if (config->estop_line >= 0) {
          auto line = GpioLine::input(chip.value(), config->estop_line, "vdrig-estop", config->estop_active_low,
                                      config->estop_active_low);
          if (!line) return line.error();
          estop = std::make_unique<GpiodInput>(std::move(line.value()));
        }
        return std::unique_ptr<PanTiltStage>(std::make_unique<StepDirStage>(
            std::move(config.value()), std::move(pan.value()), std::move(tilt.value()), std::move(estop)));
      },
      {.check = settings_check(StepDirStageConfig::parse)});
  registry.add_light("gpio",
                     [](const nlohmann::json& settings, RigContext&) -> Result<std::unique_ptr<Light>> {
                       auto config = GpioLightConfig::parse(settings);
                       if (!config) return config.error();
                       return GpioLight::create(config.value());
                     },
                     {.check = settings_check(GpioLightConfig::parse)});
}

}  // namespace vdrig::rig

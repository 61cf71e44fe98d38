// Thin RAII wrappers over libgpiod v1.6 lines (the C API; gpiod.h stays inside gpiod_lines.cpp). Shared by the
// gpio-stepdir stage and the gpio light.
#pragma once

#include <memory>
#include <string>

#include "vdrig/core/result.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace vdrig::rig {

class GpioChip {
 public:
  /// Opens a chip by name ("gpiochip0"), path ("/dev/gpiochip0"), label or number (gpiod_chip_open_lookup), and
  /// locks its node for this process (core/process_lock.hpp: kInUse naming the PID of another process holding it).
  /// Opened again in this process while open, it is the same chip.
  static Result<std::shared_ptr<GpioChip>> open(const std::string& name);
  ~GpioChip();
  GpioChip(const GpioChip&) = delete;
  GpioChip& operator=(const GpioChip&) = delete;
  const std::string& name() const { return name_; }
  int num_lines() const;
  gpiod_chip* raw() const { return chip_; }

 private:
  GpioChip(gpiod_chip* chip, std::string name, int lock_fd) : chip_(chip), name_(std::move(name)), lock_fd_(lock_fd) {}
  gpiod_chip* chip_;
  std::string name_;
  int lock_fd_;  // the chip's node, open only to hold its flock
};

/// One requested line. Values are logical (active_low is applied by the kernel): true = active.
class GpioLine {
 public:
  static Result<std::unique_ptr<GpioLine>> output(std::shared_ptr<GpioChip> chip, int offset,
                                                  const std::string& consumer, bool active_low, bool initial);
  static Result<std::unique_ptr<GpioLine>> input(std::shared_ptr<GpioChip> chip, int offset,
                                                 const std::string& consumer, bool active_low, bool pull_up);
  ~GpioLine();
  GpioLine(const GpioLine&) = delete;
  GpioLine& operator=(const GpioLine&) = delete;

  Status set(bool active);
  Result<bool> get();
  int offset() const { return offset_; }

 private:
  GpioLine(std::shared_ptr<GpioChip> chip, gpiod_line* line, int offset)
      : chip_(std::move(chip)), line_(line), offset_(offset) {}
  Error failure(const char* what, int err) const;
  std::shared_ptr<GpioChip> chip_;  // keeps the chip open while the line is held
  gpiod_line* line_;
  int offset_;
};

}  // namespace vdrig::rig

#include "gpiod_lines.hpp"

#include <fcntl.h>
#include <gpiod.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <mutex>

#include "backends.hpp"
#include "vdrig/core/process_lock.hpp"

namespace vdrig::rig {

Result<std::shared_ptr<GpioChip>> GpioChip::open(const std::string& name) {
  // The chips this process has open, by node: a stage and a light on one chip share it, and so its lock (a second
  // flock of the node from this process would refuse the light).
  static std::mutex open_chips_mutex;
  static std::map<std::string, std::weak_ptr<GpioChip>> open_chips;
  gpiod_chip* chip = gpiod_chip_open_lookup(name.c_str());
  if (!chip) {
    const int err = errno;
    return make_error(err == ENOENT || err == ENODEV ? ErrorCode::kNotFound : ErrorCode::kDevice,
                      "gpio chip \"" + name + "\": " + std::strerror(err));
  }
  const std::string node = std::string("/dev/") + gpiod_chip_name(chip);
  std::lock_guard lock(open_chips_mutex);
  if (auto shared = open_chips[node].lock()) {
    gpiod_chip_close(chip);
    return shared;
  }
  // libgpiod 1.6 does not expose the chip's descriptor: the node is opened once more to be locked (flock conflicts
  // between open files of one node, so it excludes other processes all the same).
  const int lock_fd = ::open(node.c_str(), O_RDONLY | O_CLOEXEC);
  if (lock_fd < 0) {
    const int err = errno;
    gpiod_chip_close(chip);
    return make_error(ErrorCode::kDevice, "gpio chip " + node + ": " + std::strerror(err));
  }
  if (Status locked = lock_open_file(lock_fd, "gpio chip " + node); !locked) {
    ::close(lock_fd);
    gpiod_chip_close(chip);
    return locked.error();
  }
  std::shared_ptr<GpioChip> opened(new GpioChip(chip, name, lock_fd));
  open_chips[node] = opened;
  return opened;
}

GpioChip::~GpioChip() {
  gpiod_chip_close(chip_);
  ::close(lock_fd_);  // releases the chip's lock
}

int GpioChip::num_lines() const { return static_cast<int>(gpiod_chip_num_lines(chip_)); }

namespace {

Result<gpiod_line*> get_line(const GpioChip& chip, int offset) {
  if (offset < 0 || offset >= chip.num_lines())
    return make_error(ErrorCode::kInvalidArgument, "gpio chip \"" + chip.name() + "\" has no line " +
                                                       std::to_string(offset) + " (it has " +
                                                       std::to_string(chip.num_lines()) + ")");
  gpiod_line* line = gpiod_chip_get_line(chip.raw(), static_cast<unsigned>(offset));
  if (!line)
    return make_error(ErrorCode::kDevice,
                      "gpio chip \"" + chip.name() + "\" line " + std::to_string(offset) + ": " + std::strerror(errno));
  return line;
}

}  // namespace

Error GpioLine::failure(const char* what, int err) const {
  // A USB GPIO expander that was unplugged answers ENODEV.
  const ErrorCode code = err == ENODEV || err == ENXIO ? ErrorCode::kDisconnected : ErrorCode::kDevice;
  return make_error(code, std::string(what) + " gpio " + chip_->name() + ":" + std::to_string(offset_) + ": " +
                              std::strerror(err) + (err == EBUSY ? " (line held by another consumer)" : ""));
}

Result<std::unique_ptr<GpioLine>> GpioLine::output(std::shared_ptr<GpioChip> chip, int offset,
                                                   const std::string& consumer, bool active_low, bool initial) {
  auto line = get_line(*chip, offset);
  if (!line) return line.error();
  std::unique_ptr<GpioLine> l(new GpioLine(chip, *line, offset));
  const int flags = active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_output_flags(*line, consumer.c_str(), flags, initial ? 1 : 0) != 0) {
    l->line_ = nullptr;  // not requested: nothing to release
    return GpioLine(chip, nullptr, offset).failure("requesting output", errno);
  }
  return l;
}

Result<std::unique_ptr<GpioLine>> GpioLine::input(std::shared_ptr<GpioChip> chip, int offset,
                                                  const std::string& consumer, bool active_low, bool pull_up) {
  auto line = get_line(*chip, offset);
  if (!line) return line.error();
  std::unique_ptr<GpioLine> l(new GpioLine(chip, *line, offset));
  // Limit switches are usually wired to ground with the SoC's pull-up; the bias flag needs kernel >= 5.5 and is
  // ignored by chips without bias control, so an external pull-up still works.
  const int flags =
      (active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0) | (pull_up ? GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP : 0);
  if (gpiod_line_request_input_flags(*line, consumer.c_str(), flags) != 0) {
    l->line_ = nullptr;
    return GpioLine(chip, nullptr, offset).failure("requesting input", errno);
  }
  return l;
}

GpioLine::~GpioLine() {
  if (line_) gpiod_line_release(line_);
}

Status GpioLine::set(bool active) {
  if (gpiod_line_set_value(line_, active ? 1 : 0) != 0) return failure("setting", errno);
  return Status::ok();
}

Result<bool> GpioLine::get() {
  const int v = gpiod_line_get_value(line_);
  if (v < 0) return failure("reading", errno);
  return v == 1;
}

DeviceKind list_gpio_chips() {
  DeviceKind k{"GPIO chips (gpio-stepdir, gpio light)", {}, ""};
  for (const auto& path : device_entries("/dev", "gpiochip")) {
    gpiod_chip* chip = gpiod_chip_open(path.c_str());
    if (!chip) {
      k.devices.push_back({path.string(), std::string("cannot open: ") + std::strerror(errno)});
      continue;
    }
    const unsigned lines = gpiod_chip_num_lines(chip);
    std::string summary = std::string(gpiod_chip_label(chip)) + ", " + std::to_string(lines) + " lines";
    std::string names;
    for (unsigned i = 0; i < lines; ++i) {
      gpiod_line* line = gpiod_chip_get_line(chip, i);
      const char* n = line ? gpiod_line_name(line) : nullptr;
      if (n && *n) names += (names.empty() ? "" : " ") + std::to_string(i) + "=" + n;
    }
    summary += names.empty() ? " (no line names)" : ": " + names;
    gpiod_chip_close(chip);
    k.devices.push_back({path.string(), summary});
  }
  return k;
}

}  // namespace vdrig::rig

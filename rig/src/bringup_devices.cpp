// list_devices (bringup.hpp): what `vdrig rig devices` prints. Each kind is searched the way its backend opens it.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "vdrig/rig/bringup.hpp"
#ifdef VDRIG_HAVE_GPIOD
#include <gpiod.h>
#endif
#ifdef VDRIG_HAVE_USB
#include "usb_ptp_camera.hpp"
#endif
#ifdef VDRIG_HAVE_LIBCAMERA
#include "libcamera_camera.hpp"
#endif
#ifdef VDRIG_HAVE_GPHOTO2
#include "gphoto2_camera.hpp"
#endif

namespace vdrig::rig {
namespace {
namespace fs = std::filesystem;

/// Entries of `dir` whose name starts with `prefix`, sorted naturally enough (video2 before video10).
std::vector<fs::path> entries(const fs::path& dir, const std::string& prefix) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().filename().string().rfind(prefix, 0) == 0) out.push_back(e.path());
  std::sort(out.begin(), out.end(), [](const fs::path& a, const fs::path& b) {
    const std::string x = a.filename().string(), y = b.filename().string();
    return x.size() != y.size() ? x.size() < y.size() : x < y;
  });
  return out;
}

std::string control_range(int fd, uint32_t id, const char* name) {
  v4l2_queryctrl q{};
  q.id = id;
  if (::ioctl(fd, VIDIOC_QUERYCTRL, &q) != 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) return "";
  return std::string(name) + " " + std::to_string(q.minimum) + ".." + std::to_string(q.maximum) + " (default " +
         std::to_string(q.default_value) + ")";
}

DeviceKind v4l2_cameras() {
  DeviceKind k{"V4L2 cameras", {}, ""};
  for (const auto& path : entries("/dev", "video")) {
    const int fd = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
      k.devices.push_back({path.string(), std::string("cannot open: ") + std::strerror(errno)});
      continue;
    }
    v4l2_capability cap{};
    if (::ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0) {
      const uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
      if (caps & V4L2_CAP_VIDEO_CAPTURE) {  // metadata and output nodes of the same camera are left out
        std::string summary = std::string(reinterpret_cast<const char*>(cap.card)) + " (" +
                              reinterpret_cast<const char*>(cap.driver) + ", " +
                              reinterpret_cast<const char*>(cap.bus_info) + ")";
        std::string controls;
        for (const auto& c : {control_range(fd, V4L2_CID_EXPOSURE_AUTO, "exposure_auto"),
                              control_range(fd, V4L2_CID_EXPOSURE_ABSOLUTE, "exposure_absolute [100 us]"),
                              control_range(fd, V4L2_CID_GAIN, "gain")})
          if (!c.empty()) controls += (controls.empty() ? "" : ", ") + c;
        summary += controls.empty() ? "; no manual exposure control (not usable for a bracket)" : "; " + controls;
        k.devices.push_back({path.string(), summary});
      }
    }
    ::close(fd);
  }
  return k;
}

DeviceKind libcamera_cameras() {
  DeviceKind k{"libcamera cameras", {}, ""};
#ifdef VDRIG_HAVE_LIBCAMERA
  auto cameras = list_libcamera_cameras();
  if (!cameras)
    k.note = cameras.error().message;
  else
    for (const auto& c : cameras.value()) k.devices.push_back({c, ""});
#else
  k.note = "libcamera backend not built";
#endif
  return k;
}

DeviceKind usb_ptp_cameras() {
  DeviceKind k{"USB PTP still cameras", {}, ""};
#ifdef VDRIG_HAVE_USB
  auto cameras = list_usb_still_cameras();
  if (!cameras) {
    k.note = cameras.error().message;
    return k;
  }
  for (const auto& c : cameras.value()) {
    char ids[32];
    std::snprintf(ids, sizeof ids, "%04x:%04x", c.vendor_id, c.product_id);
    std::string summary = std::string("vendor_id ") + std::string(ids, 4) + ", product_id " + std::string(ids + 5);
    if (c.product.empty())
      summary += "; cannot open it for its names (permissions? see docs/hardware.md)";
    else
      summary += "; " + c.manufacturer + " " + c.product + (c.serial.empty() ? "" : ", serial " + c.serial);
    k.devices.push_back({"usb:" + std::to_string(c.bus) + ":" + std::to_string(c.address), summary});
  }
#else
  k.note = "usb-ptp backend not built";
#endif
  return k;
}

DeviceKind gphoto2_cameras() {
  DeviceKind k{"gphoto2 cameras (libgphoto2)", {}, ""};
#ifdef VDRIG_HAVE_GPHOTO2
  auto cameras = list_gphoto2_cameras();
  if (!cameras)
    k.note = cameras.error().message;
  else
    for (const auto& c : cameras.value())  // the model and port a "gphoto2" camera section takes
      k.devices.push_back({c.port, "model \"" + c.model + "\""});
#else
  k.note = "gphoto2 backend not built";
#endif
  return k;
}

std::string read_line(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  return line;
}

DeviceKind serial_ports() {
  // A tty with a device behind it in sysfs is a real port (the kernel's virtual consoles have none); legacy
  // ttyS ports that exist only as placeholders report port type 0 (unknown).
  DeviceKind k{"serial ports (modbus-rtu)", {}, ""};
  for (const auto& tty : entries("/sys/class/tty", "tty")) {
    const std::string name = tty.filename().string();
    std::error_code ec;
    if (!fs::exists(tty / "device", ec)) continue;
    if (name.rfind("ttyS", 0) == 0 && read_line(tty / "type") == "0") continue;
    const std::string driver = fs::read_symlink(tty / "device" / "driver", ec).filename().string();
    std::string summary = driver.empty() ? "" : "driver " + driver;
    // A USB adapter's names are two levels up (interface -> device).
    for (const auto& up : {tty / "device" / ".." / "product", tty / "device" / ".." / ".." / "product"})
      if (fs::exists(up, ec)) {
        summary += (summary.empty() ? "" : ", ") + read_line(up);
        break;
      }
    k.devices.push_back({"/dev/" + name, summary});
  }
  return k;
}

DeviceKind gpio_chips() {
  DeviceKind k{"GPIO chips (gpio-stepdir, gpio light)", {}, ""};
#ifdef VDRIG_HAVE_GPIOD
  for (const auto& path : entries("/dev", "gpiochip")) {
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
#else
  k.note = "gpiod backends not built";
#endif
  return k;
}

}  // namespace

std::vector<DeviceKind> list_devices() {
  return {v4l2_cameras(), libcamera_cameras(), usb_ptp_cameras(), gphoto2_cameras(), serial_ports(), gpio_chips()};
}

}  // namespace vdrig::rig

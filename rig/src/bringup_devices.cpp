// list_devices (bringup.hpp): what `vdrig rig devices` prints. Each kind is searched the way its backend opens it;
// the kinds that need a backend's library are searched by that backend (list_backend_devices, backend_list.cpp).
#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "backends.hpp"
#include "vdrig/rig/bringup.hpp"

namespace vdrig::rig {
namespace fs = std::filesystem;

std::vector<fs::path> device_entries(const fs::path& dir, const std::string& prefix) {
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

namespace {

std::string control_range(int fd, uint32_t id, const char* name) {
  v4l2_queryctrl q{};
  q.id = id;
  if (::ioctl(fd, VIDIOC_QUERYCTRL, &q) != 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) return "";
  return std::string(name) + " " + std::to_string(q.minimum) + ".." + std::to_string(q.maximum) + " (default " +
         std::to_string(q.default_value) + ")";
}

DeviceKind v4l2_cameras() {
  DeviceKind k{"V4L2 cameras", {}, ""};
  for (const auto& path : device_entries("/dev", "video")) {
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
  for (const auto& tty : device_entries("/sys/class/tty", "tty")) {
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

}  // namespace

std::vector<DeviceKind> list_devices() {
  // The kinds searched without a backend's library here; the others are the backends' own (backend_list.cpp).
  std::vector<DeviceKind> kinds = {v4l2_cameras()};
  for (auto& kind : list_backend_devices()) kinds.push_back(std::move(kind));
  kinds.push_back(serial_ports());
  return kinds;
}

}  // namespace vdrig::rig

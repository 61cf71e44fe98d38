// What the hardware backends' sources share with bring-up: the device listings of `vdrig rig devices`. Each is
// defined in its backend's source file, compiled only when its option is on and its library was found (rig_backend
// in rig/CMakeLists.txt); backend_list.cpp, the one source that sees the VDRIG_HAVE_<NAME> definitions, calls those
// built. The registration functions are declared in backend_list.cpp alone, so that adding a backend recompiles
// that file and the backend's own, not every backend.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {

// `vdrig rig devices` (list_devices): the devices a backend's library finds, searched the way it opens them.
DeviceKind list_libcamera_devices();  // libcamera_camera.cpp
DeviceKind list_usb_ptp_devices();    // usb_ptp_camera.cpp
DeviceKind list_gphoto2_devices();    // gphoto2_camera.cpp
DeviceKind list_gpio_chips();         // gpiod_lines.cpp
/// The kinds above in list_devices' order, each built backend's searched and the others' with a "not built" note
/// (backend_list.cpp).
std::vector<DeviceKind> list_backend_devices();

/// Entries of `dir` whose name starts with `prefix`, sorted naturally enough (video2 before video10)
/// (bringup_devices.cpp).
std::vector<std::filesystem::path> device_entries(const std::filesystem::path& dir, const std::string& prefix);

}  // namespace vdrig::rig

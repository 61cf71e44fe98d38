// The hooks of the hardware backends. Each is defined in its backend's source file, which is compiled only when its
// option is on and its library was found (rig_backend in rig/CMakeLists.txt); backend_list.cpp, the one source that
// sees the VDRIG_HAVE_<NAME> definitions, calls those built.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {

// Registration: the backend's factory and settings parser (BackendSpec::check).
void register_modbus_backends(BackendRegistry& registry);    // stage: modbus-tcp, modbus-rtu
void register_gpiod_backends(BackendRegistry& registry);     // stage: gpio-stepdir; light: gpio
void register_v4l2_backend(BackendRegistry& registry);       // camera: v4l2
void register_libcamera_backend(BackendRegistry& registry);  // camera: libcamera
void register_usb_ptp_backend(BackendRegistry& registry);    // camera: usb-ptp (PTP over libusb)
void register_gphoto2_backend(BackendRegistry& registry);    // camera: gphoto2 (libgphoto2)

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

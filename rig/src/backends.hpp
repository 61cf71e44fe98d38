// Registration hooks of the hardware backends. Each is defined in its backend's source file, which is compiled only
// when its option is on and its library was found (VDRIG_HAVE_<NAME>, defined by rig_backend in rig/CMakeLists.txt);
// hardware.cpp calls those built.
#pragma once

#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {

void register_modbus_backends(BackendRegistry& registry);    // stage: modbus-tcp, modbus-rtu
void register_gpiod_backends(BackendRegistry& registry);     // stage: gpio-stepdir; light: gpio
void register_v4l2_backend(BackendRegistry& registry);       // camera: v4l2
void register_libcamera_backend(BackendRegistry& registry);  // camera: libcamera
void register_usb_ptp_backend(BackendRegistry& registry);    // camera: usb-ptp (PTP over libusb)
void register_gphoto2_backend(BackendRegistry& registry);    // camera: gphoto2 (libgphoto2)

}  // namespace vdrig::rig

// The list of the hardware backends built into rig: the one source that sees their VDRIG_HAVE_<NAME> definitions
// (rig_backend in rig/CMakeLists.txt), so that switching a backend on or off recompiles this file alone.
#include "backends.hpp"

namespace vdrig::rig {

// Each backend's registration (its factory and settings parser, BackendSpec::check), defined in its source file.
void register_modbus_backends(BackendRegistry& registry);    // stage: modbus-tcp, modbus-rtu
void register_gpiod_backends(BackendRegistry& registry);     // stage: gpio-stepdir; light: gpio
void register_v4l2_backend(BackendRegistry& registry);       // camera: v4l2
void register_libcamera_backend(BackendRegistry& registry);  // camera: libcamera
void register_usb_ptp_backend(BackendRegistry& registry);    // camera: usb-ptp (PTP over libusb)
void register_gphoto2_backend(BackendRegistry& registry);    // camera: gphoto2 (libgphoto2)

// Each hardware backend adds itself here, guarded by its VDRIG_HAVE_<NAME>.
void register_hardware_backends([[maybe_unused]] BackendRegistry& registry) {
#ifdef VDRIG_HAVE_MODBUS
  register_modbus_backends(registry);
#endif
#ifdef VDRIG_HAVE_GPIOD
  register_gpiod_backends(registry);
#endif
#ifdef VDRIG_HAVE_V4L2
  register_v4l2_backend(registry);
#endif
#ifdef VDRIG_HAVE_LIBCAMERA
  register_libcamera_backend(registry);
#endif
#ifdef VDRIG_HAVE_USB
  register_usb_ptp_backend(registry);
#endif
#ifdef VDRIG_HAVE_GPHOTO2
  register_gphoto2_backend(registry);
#endif
}

std::vector<DeviceKind> list_backend_devices() {
  std::vector<DeviceKind> kinds;
#ifdef VDRIG_HAVE_LIBCAMERA
  kinds.push_back(list_libcamera_devices());
#else
  kinds.push_back({"libcamera cameras", {}, "libcamera backend not built"});
#endif
#ifdef VDRIG_HAVE_USB
  kinds.push_back(list_usb_ptp_devices());
#else
  kinds.push_back({"USB PTP still cameras", {}, "usb-ptp backend not built"});
#endif
#ifdef VDRIG_HAVE_GPHOTO2
  kinds.push_back(list_gphoto2_devices());
#else
  kinds.push_back({"gphoto2 cameras (libgphoto2)", {}, "gphoto2 backend not built"});
#endif
#ifdef VDRIG_HAVE_GPIOD
  kinds.push_back(list_gpio_chips());
#else
  kinds.push_back({"GPIO chips (gpio-stepdir, gpio light)", {}, "gpiod backends not built"});
#endif
  return kinds;
}

}  // namespace vdrig::rig

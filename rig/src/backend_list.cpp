#include "backends.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {

// Each hardware backend adds itself here, guarded by its VDRIG_HAVE_<NAME> (rig_backend in rig/CMakeLists.txt).
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

}  // namespace vdrig::rig

// "usb-ptp" camera: finds a still camera on USB (interface class 6, Still Image / PTP) through libusb.
// Only discovery is implemented: info() names the camera; set_exposure() and capture() return kUnsupported (a PTP
// capture needs the vendor's operation set and object transfer, better left to libgphoto2 when it is wanted).
//
// Settings: "vendor_id" / "product_id" (hex strings like "04a9", optional filters), "index" (0: which of the
// matching cameras).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

struct UsbStillCamera {
  uint16_t vendor_id = 0, product_id = 0;
  int bus = 0, address = 0;
  std::string manufacturer, product;  // empty when the device could not be opened (permissions)
};

/// Every USB device with an interface of class 6 (still image).
Result<std::vector<UsbStillCamera>> list_usb_still_cameras();

class UsbPtpCamera final : public Camera {
 public:
  /// kNotFound when no matching still camera is attached.
  static Result<std::unique_ptr<Camera>> create(const nlohmann::json& settings);
  std::string backend() const override { return "usb-ptp"; }
  Result<CameraInfo> info() override;
  Status set_exposure(double exposure_s, double gain) override;
  Result<Frame> capture() override;

 private:
  explicit UsbPtpCamera(UsbStillCamera dev) : dev_(std::move(dev)) {}
  UsbStillCamera dev_;
};

}  // namespace vdrig::rig

// "usb-ptp" camera: a still camera on USB (interface class 6, Still Image) driven with PTP (ISO 15740) over bulk
// transfers through libusb: InitiateCapture, wait for ObjectAdded, GetObject, decode the JPEG. The protocol itself
// is in ptp_protocol.{hpp,cpp} (no USB code, tested against a fake camera); docs/rig-ptp.md has the details.
//
// Settings (JSON "camera" section):
//   "vendor_id" / "product_id" (hex strings like "04a9", optional filters), "index" (0: which of the matching
//   cameras), "timeout_s" (5: per USB transfer), "capture_timeout_s" (30: InitiateCapture to ObjectAdded, on top of
//   the exposure), "complete_grace_s" (1: how long to wait for CaptureComplete / more objects after the first
//   ObjectAdded), "keep_on_card" (false: each photo is deleted from the camera once downloaded), "base_iso" (100:
//   gain 1 is this ISO; gain g asks for ISO g * base_iso), "busy_retries" (20: DeviceBusy answers tolerated).
// set_exposure() picks the supported ExposureTime (and ISO) nearest in stops and capture() reports what was used.
// kDisconnected when the camera went away; the next call reopens it. The capture flow (download, decode, delete) and
// its errors are StillCamera's (still_camera.hpp), shared with the gphoto2 backend.
#pragma once

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "ptp_protocol.hpp"
#include "still_camera.hpp"

namespace vdrig::rig {

struct UsbStillCamera {
  uint16_t vendor_id = 0, product_id = 0;
  int bus = 0, address = 0;
  std::string manufacturer, product, serial;  // empty when the device could not be opened (permissions)
};

/// Every USB device with an interface of class 6 (still image).
Result<std::vector<UsbStillCamera>> list_usb_still_cameras();

struct UsbPtpConfig {
  std::optional<uint16_t> vendor_id, product_id;
  int index = 0;
  double timeout_s = 5.0;
  double capture_timeout_s = 30.0;
  double complete_grace_s = 1.0;
  bool keep_on_card = false;
  double base_iso = 100.0;
  int busy_retries = 20;
  /// Validates every key up front (kInvalidArgument listing each problem).
  static Result<UsbPtpConfig> parse(const nlohmann::json& settings);
  /// The settings as the backend uses them, defaults filled in, in the section's JSON keys (`vdrig rig check`).
  nlohmann::json effective() const;
  ptp::SessionOptions session_options() const;
};

/// Opens the transport to the camera; called again to reconnect after the camera went away.
using PtpTransportFactory = std::function<Result<std::unique_ptr<ptp::PtpTransport>>()>;

/// libusb transport to the `config.index`-th matching still camera (kNotFound when there is none).
Result<std::unique_ptr<ptp::PtpTransport>> open_usb_ptp_transport(const UsbPtpConfig& config);

class UsbPtpCamera final : public StillCamera {
 public:
  /// Parses the settings and opens the camera over USB. kNotFound when no matching still camera is attached.
  static Result<std::unique_ptr<Camera>> create(const nlohmann::json& settings);
  /// The same camera over any transport (the tests use a fake camera). Opens the PTP session at once.
  static Result<std::unique_ptr<UsbPtpCamera>> create_with(UsbPtpConfig config, PtpTransportFactory open_transport,
                                                           ptp::SessionOptions options);
  ~UsbPtpCamera() override;

  std::string backend() const override { return "usb-ptp"; }
  // info(): model from GetDeviceInfo; width/height of the last photograph (0 before the first); exposure range from
  // the camera's ExposureTime description; auto_exposure_on when ExposureTime cannot be set.

  /// What the camera reported at open (empty before).
  const ptp::DeviceInfo& device_info() const { return device_info_; }

 private:
  UsbPtpCamera(UsbPtpConfig config, PtpTransportFactory open_transport, ptp::SessionOptions options);
  bool connected() const override { return session_ != nullptr; }
  Status connect() override;
  Status apply_exposure() override;
  Result<std::vector<StillFile>> trigger() override;
  Result<std::vector<uint8_t>> download(const StillFile& file) override;
  Status remove(const StillFile& file) override;
  bool can_remove() const override { return device_info_.supports_operation(ptp::kDeleteObject); }
  Error link_error(Error e) override { return failed(std::move(e)); }
  void drop();
  /// Drops the session after errors that leave the USB stream out of step, so the next call reopens.
  Error failed(Error e);
  std::string name() const;

  UsbPtpConfig config_;
  PtpTransportFactory open_transport_;
  ptp::SessionOptions options_;
  std::unique_ptr<ptp::PtpTransport> transport_;
  std::unique_ptr<ptp::PtpSession> session_;
  ptp::DeviceInfo device_info_;
  std::optional<ptp::PropDesc> exposure_desc_, iso_desc_;
};

}  // namespace vdrig::rig

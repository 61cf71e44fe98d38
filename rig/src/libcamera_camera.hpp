// "libcamera" camera (Raspberry Pi and other libcamera-supported sensors), libcamera C++ API 0.0.3.
// Configured once for StillCapture; each capture queues one request with ExposureTime / AnalogueGain and
// AeEnable = false, waits for it, and converts the buffer to BGR. The pipeline is started per capture, which costs
// some frames of latency but guarantees the request's controls apply to the frame returned.
//
// Settings (JSON "camera" section): "camera_id" ("" = the first camera), "width"/"height" (0 = the pipeline's
// default still size), "timeout_s" (5, on top of the exposure).
// libcamera types stay in the .cpp (pimpl).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

/// The cameras libcamera sees: "id (model)" each; kDevice when the camera manager does not start.
Result<std::vector<std::string>> list_libcamera_cameras();

struct LibcameraConfig {
  std::string camera_id;  // "" = the first camera
  int width = 0, height = 0;
  double timeout_s = 5.0;
  /// Validates every key up front (kInvalidArgument listing each problem).
  static Result<LibcameraConfig> parse(const nlohmann::json& settings);
  /// The settings as used, defaults filled in (`vdrig rig check`).
  nlohmann::json effective() const;
};

class LibcameraCamera final : public Camera {
 public:
  /// kNotFound when libcamera sees no camera (or not the one named).
  static Result<std::unique_ptr<Camera>> create(const LibcameraConfig& config);
  ~LibcameraCamera() override;
  std::string backend() const override { return "libcamera"; }
  Result<CameraInfo> info() override;
  Status set_exposure(double exposure_s, double gain) override;
  Result<Frame> capture() override;

  struct Impl;

 private:
  explicit LibcameraCamera(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vdrig::rig

// "v4l2" camera: a UVC webcam or any V4L2 capture device, through libv4l2 (which also papers over driver quirks).
// One capture = stream on, drop `discard_frames` frames (the new exposure reaches the sensor a frame or two late),
// keep the next, stream off: slow but every frame is taken with the settings asked for.
//
// Settings (JSON "camera" section): "device" ("/dev/video0"), "width"/"height" (0 = keep the device's),
//   "pixel_format" ("YUYV"; any V4L2 fourcc that pixel_convert handles: YUYV UYVY NV12 BGR3 RGB3 GREY Y10 Y12 Y16
//   MJPG ...), "discard_frames" (2), "buffers" (4), "timeout_s" (2, on top of the exposure),
//   "gain_control_per_unit" (1: the V4L2 gain control is device-specific; the value written is
//   round(gain * gain_control_per_unit)).
// Exposure goes to V4L2_CID_EXPOSURE_ABSOLUTE in 100 us units with auto exposure, exposure priority and auto gain
// switched off. A device that goes away is kDisconnected; the next call reopens it.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

struct V4l2CameraConfig {
  std::string device = "/dev/video0";
  int width = 0, height = 0;
  uint32_t fourcc = 0;
  int discard_frames = 2;
  int buffers = 4;
  double timeout_s = 2.0;
  double gain_control_per_unit = 1.0;
  static Result<V4l2CameraConfig> parse(const nlohmann::json& settings);
  /// The settings as the backend uses them, defaults filled in, in the section's JSON keys (`vdrig rig check`).
  nlohmann::json effective() const;
};

class V4l2Camera final : public Camera {
 public:
  static Result<std::unique_ptr<Camera>> create(const nlohmann::json& settings);
  ~V4l2Camera() override;
  std::string backend() const override { return "v4l2"; }
  Result<CameraInfo> info() override;
  Status set_exposure(double exposure_s, double gain) override;
  Result<Frame> capture() override;

 private:
  explicit V4l2Camera(V4l2CameraConfig c) : config_(std::move(c)) {}
  Status open();
  void close();
  Error errno_error(const std::string& what, int err);
  Status apply_exposure();
  Result<cv::Mat> grab(int64_t* timestamp_ns, uint32_t* sequence);

  V4l2CameraConfig config_;
  int fd_ = -1;
  CameraInfo info_;
  uint32_t fourcc_ = 0;
  int bytesperline_ = 0;
  int32_t exposure_min_ = 1, exposure_max_ = 100000;  // 100 us units
  bool has_gain_ = false;
  uint32_t gain_cid_ = 0;
  int32_t gain_min_ = 0, gain_max_ = 0;
  double exposure_s_ = 0.01;  // what was asked
  double gain_ = 1.0;
  double used_exposure_s_ = 0.0;  // what the device took
  double used_gain_ = 1.0;
  uint64_t captures_ = 0;
};

}  // namespace vdrig::rig

// Frame: one photograph as it leaves the camera, with the exposure and the pose it was taken at.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

namespace vdrig {

/// Pan/tilt position of the turntable, radians (degrees only at the edges: config, CLI, JSON).
struct PanTilt {
  double pan_rad = 0.0;
  double tilt_rad = 0.0;
};

/// One photograph: pixels as the camera delivered them (CV_8UC3 or CV_16UC3, BGR, codes of its response curve),
/// the exposure it was taken with, and both the commanded and the measured (read back) pose.
struct Frame {
  cv::Mat image;
  double exposure_s = 0.0;
  double gain = 1.0;
  int bits = 8;  // significant bits of a code (8, 10, 12, 16): saturation is (1 << bits) - 1
  PanTilt commanded;
  PanTilt measured;
  int64_t timestamp_ns = 0;  // CLOCK_REALTIME at exposure start
  uint64_t sequence = 0;     // camera's frame counter; a gap means a dropped frame
};

}  // namespace vdrig

// Camera buffers -> the BGR cv::Mat a Frame carries (CV_8UC3, or CV_16UC3 for >8-bit sensors). Pure functions, no
// device access, shared by the v4l2 and libcamera backends and tested on synthetic buffers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::rig {

/// Memory layouts we convert, named by byte order in memory (not by fourcc, whose naming differs between V4L2
/// and DRM/libcamera).
enum class PixelLayout {
  kBGR24,   // B G R
  kRGB24,   // R G B
  kBGRX32,  // B G R X
  kRGBX32,  // R G B X
  kYUYV,    // Y0 U Y1 V (4:2:2)
  kUYVY,    // U Y0 V Y1 (4:2:2)
  kNV12,    // Y plane, then interleaved U V plane at half resolution (4:2:0)
  kGrey8,
  kGrey16,  // little-endian 16-bit words, value in the low `bits` bits (V4L2 Y10/Y12/Y16)
  kMJPEG,   // a JPEG per frame (UVC webcams)
};

const char* to_string(PixelLayout layout);

/// One frame as the device left it. `stride` is the bytes per line of the first plane (0 = tightly packed);
/// NV12's chroma plane follows the luma plane at height * stride.
struct PixelBuffer {
  const uint8_t* data = nullptr;
  size_t bytes = 0;
  int width = 0;
  int height = 0;
  size_t stride = 0;
  PixelLayout layout = PixelLayout::kBGR24;
  int bits = 8;  // significant bits for kGrey16
};

/// Converts to BGR: CV_8UC3 for 8-bit layouts, CV_16UC3 for kGrey16 (codes unscaled: saturation stays
/// (1 << bits) - 1). The result owns its pixels. kCorrupt when the buffer is too short or a JPEG does not decode.
Result<cv::Mat> to_bgr(const PixelBuffer& buffer);

/// The layout of a V4L2 pixel format (V4L2_PIX_FMT_*), with its significant bits; nullopt when unsupported.
std::optional<PixelLayout> layout_from_v4l2(uint32_t fourcc, int* bits);

/// "YUYV" for a fourcc code (for messages and settings).
std::string fourcc_to_string(uint32_t fourcc);
/// The code of a four-character string; nullopt unless exactly 4 characters.
std::optional<uint32_t> fourcc_from_string(const std::string& s);

/// V4L2_CID_EXPOSURE_ABSOLUTE counts 100 us units.
inline constexpr double kV4l2ExposureUnitS = 100e-6;
/// Exposure time -> V4L2 control value, rounded to the nearest unit and clamped to [min_units, max_units].
inline int32_t v4l2_exposure_units(double exposure_s, int32_t min_units, int32_t max_units) {
  const double u = exposure_s / kV4l2ExposureUnitS + 0.5;
  if (!(u >= static_cast<double>(min_units))) return min_units;  // also catches NaN
  if (u >= static_cast<double>(max_units)) return max_units;
  return static_cast<int32_t>(u);
}
inline double v4l2_exposure_s(int32_t units) { return units * kV4l2ExposureUnitS; }

}  // namespace vdrig::rig

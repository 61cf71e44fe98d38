#include "pixel_convert.hpp"

#include <linux/videodev2.h>

#include <opencv2/imgproc.hpp>
#include <vector>

#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"

namespace vdrig::rig {

const char* to_string(PixelLayout layout) {
  switch (layout) {
    case PixelLayout::kBGR24:
      return "BGR24";
    case PixelLayout::kRGB24:
      return "RGB24";
    case PixelLayout::kBGRX32:
      return "BGRX32";
    case PixelLayout::kRGBX32:
      return "RGBX32";
    case PixelLayout::kYUYV:
      return "YUYV";
    case PixelLayout::kUYVY:
      return "UYVY";
    case PixelLayout::kNV12:
      return "NV12";
    case PixelLayout::kGrey8:
      return "GREY";
    case PixelLayout::kGrey16:
      return "GREY16";
    case PixelLayout::kMJPEG:
      return "MJPEG";
  }
  return "?";
}

namespace {

size_t min_stride(PixelLayout layout, int width) {
  const size_t w = static_cast<size_t>(width);
  switch (layout) {
    case PixelLayout::kBGR24:
    case PixelLayout::kRGB24:
      return 3 * w;
    case PixelLayout::kBGRX32:
    case PixelLayout::kRGBX32:
      return 4 * w;
    case PixelLayout::kYUYV:
    case PixelLayout::kUYVY:
    case PixelLayout::kGrey16:
      return 2 * w;
    case PixelLayout::kNV12:
    case PixelLayout::kGrey8:
      return w;
    case PixelLayout::kMJPEG:
      return 0;
  }
  return 0;
}

}  // namespace

Result<cv::Mat> to_bgr(const PixelBuffer& b) {
  if (b.width <= 0 || b.height <= 0 || !b.data)
    return make_error(ErrorCode::kInvalidArgument, "pixel buffer without size or data");
  if (b.layout == PixelLayout::kMJPEG) {
    // The JPEG length is what the driver reported (bytesused), not the buffer size.
    auto decoded = decode_image(std::string_view(reinterpret_cast<const char*>(b.data), b.bytes), "MJPEG frame",
                                ImageDecode::kBgr8);
    if (!decoded) return decoded.error();
    cv::Mat bgr = std::move(decoded.value());
    if (bgr.cols != b.width || bgr.rows != b.height)
      return make_error(ErrorCode::kCorrupt, "MJPEG frame is " + std::to_string(bgr.cols) + "x" +
                                                 std::to_string(bgr.rows) + ", expected " + std::to_string(b.width) +
                                                 "x" + std::to_string(b.height));
    return bgr;
  }
  if ((b.layout == PixelLayout::kYUYV || b.layout == PixelLayout::kUYVY || b.layout == PixelLayout::kNV12) &&
      (b.width % 2 != 0 || (b.layout == PixelLayout::kNV12 && b.height % 2 != 0)))
    return make_error(ErrorCode::kInvalidArgument, std::string(to_string(b.layout)) + " needs an even size");
  const size_t packed = min_stride(b.layout, b.width);
  const size_t stride = b.stride ? b.stride : packed;
  if (stride < packed)
    return make_error(ErrorCode::kInvalidArgument,
                      "stride " + std::to_string(stride) + " below the line size " + std::to_string(packed));
  const size_t rows = b.layout == PixelLayout::kNV12 ? static_cast<size_t>(b.height) * 3 / 2 : b.height;
  const size_t need = stride * (rows - 1) + packed;
  if (b.bytes < need)
    return make_error(ErrorCode::kCorrupt, std::string(to_string(b.layout)) + " buffer holds " +
                                               std::to_string(b.bytes) + " bytes, needs " + std::to_string(need));
  auto* p = const_cast<uint8_t*>(b.data);  // wrapped read-only: every path below copies into a new Mat
  const int h = b.height, w = b.width;
  cv::Mat out;
  switch (b.layout) {
    case PixelLayout::kBGR24:
      out = cv::Mat(h, w, CV_8UC3, p, stride).clone();
      break;
    case PixelLayout::kRGB24:
      cv::cvtColor(cv::Mat(h, w, CV_8UC3, p, stride), out, cv::COLOR_RGB2BGR);
      break;
    case PixelLayout::kBGRX32:
      cv::cvtColor(cv::Mat(h, w, CV_8UC4, p, stride), out, cv::COLOR_BGRA2BGR);
      break;
    case PixelLayout::kRGBX32:
      cv::cvtColor(cv::Mat(h, w, CV_8UC4, p, stride), out, cv::COLOR_RGBA2BGR);
      break;
    case PixelLayout::kYUYV:
      cv::cvtColor(cv::Mat(h, w, CV_8UC2, p, stride), out, cv::COLOR_YUV2BGR_YUYV);
      break;
    case PixelLayout::kUYVY:
      cv::cvtColor(cv::Mat(h, w, CV_8UC2, p, stride), out, cv::COLOR_YUV2BGR_UYVY);
      break;
    case PixelLayout::kNV12: {
      // OpenCV wants the two planes as one (h * 3/2) x w image; a padded stride already gives exactly that.
      cv::cvtColor(cv::Mat(h * 3 / 2, w, CV_8UC1, p, stride), out, cv::COLOR_YUV2BGR_NV12);
      break;
    }
    case PixelLayout::kGrey8:
      cv::cvtColor(cv::Mat(h, w, CV_8UC1, p, stride), out, cv::COLOR_GRAY2BGR);
      break;
    case PixelLayout::kGrey16: {
      if (b.bits < 9 || b.bits > 16)
        return make_error(ErrorCode::kInvalidArgument, "GREY16 needs 9..16 significant bits");
      // The words are little endian like the host (V4L2 Y10/Y12/Y16 are defined so; we build for little endian).
      cv::cvtColor(cv::Mat(h, w, CV_16UC1, p, stride), out, cv::COLOR_GRAY2BGR);
      break;
    }
    case PixelLayout::kMJPEG:
      break;
  }
  return out;
}

std::optional<PixelLayout> layout_from_v4l2(uint32_t fourcc, int* bits) {
  int b = 8;
  std::optional<PixelLayout> layout;
  switch (fourcc) {
    case V4L2_PIX_FMT_BGR24:
      layout = PixelLayout::kBGR24;
      break;
    case V4L2_PIX_FMT_RGB24:
      layout = PixelLayout::kRGB24;
      break;
    case V4L2_PIX_FMT_XBGR32:
    case V4L2_PIX_FMT_BGR32:
      layout = PixelLayout::kBGRX32;
      break;  // memory B G R X
    case V4L2_PIX_FMT_YUYV:
      layout = PixelLayout::kYUYV;
      break;
    case V4L2_PIX_FMT_UYVY:
      layout = PixelLayout::kUYVY;
      break;
    case V4L2_PIX_FMT_NV12:
      layout = PixelLayout::kNV12;
      break;
    case V4L2_PIX_FMT_GREY:
      layout = PixelLayout::kGrey8;
      break;
    case V4L2_PIX_FMT_Y10:
      layout = PixelLayout::kGrey16;
      b = 10;
      break;
    case V4L2_PIX_FMT_Y12:
      layout = PixelLayout::kGrey16;
      b = 12;
      break;
    case V4L2_PIX_FMT_Y16:
      layout = PixelLayout::kGrey16;
      b = 16;
      break;
    case V4L2_PIX_FMT_MJPEG:
    case V4L2_PIX_FMT_JPEG:
      layout = PixelLayout::kMJPEG;
      break;
    default:
      break;
  }
  if (layout && bits) *bits = b;
  return layout;
}

std::string fourcc_to_string(uint32_t fourcc) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    s[i] = (c >= 32 && c < 127) ? c : '?';
  }
  return s;
}

std::optional<uint32_t> fourcc_from_string(const std::string& s) {
  if (s.size() != 4) return std::nullopt;
  return v4l2_fourcc(s[0], s[1], s[2], s[3]);
}

}  // namespace vdrig::rig

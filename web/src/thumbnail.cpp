#include "thumbnail.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>

#include "vdrig/core/image_codec.hpp"

namespace vdrig::web {

std::string base64(std::string_view bytes) {
  static const char* const kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    uint32_t v = 0;
    for (std::size_t k = 0; k < 3; ++k) v = (v << 8) | (k < n ? static_cast<unsigned char>(bytes[i + k]) : 0u);
    for (std::size_t k = 0; k < 4; ++k) out += k <= n ? kAlphabet[(v >> (18 - 6 * k)) & 63] : '=';
  }
  return out;
}

Result<nlohmann::json> frame_thumbnail(std::string_view png_bytes, const std::string& name, int max_width) {
  auto decoded = decode_image(png_bytes, name);
  if (!decoded) return decoded.error();
  const cv::Mat& frame = decoded.value();
  const int depth = frame.depth();
  const int channels = frame.channels();
  if ((depth != CV_8U && depth != CV_16U) || (channels != 1 && channels != 3) || frame.empty())
    return make_error(ErrorCode::kCorrupt, name + ": not an 8/16-bit grey or BGR frame");
  const double full = depth == CV_8U ? 255.0 : 65535.0;
  const double saturated_at = kSaturatedShare * full;

  // Box filter: each thumbnail pixel is the mean of its block of frame pixels, so noise and fine texture do not alias.
  const int block = std::max(1, (frame.cols + max_width - 1) / std::max(max_width, 1));
  const int tw = frame.cols / block, th = frame.rows / block;
  cv::Mat thumb(std::max(th, 1), std::max(tw, 1), CV_8UC3, cv::Scalar::all(0));
  std::vector<double> sum(static_cast<std::size_t>(thumb.cols) * thumb.rows * 3, 0.0);
  std::size_t saturated = 0;
  auto at = [&](int y, int x, int c) {
    return depth == CV_8U ? static_cast<double>(frame.ptr<uint8_t>(y)[x * channels + c])
                          : static_cast<double>(frame.ptr<uint16_t>(y)[x * channels + c]);
  };
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x) {
      bool sat = false;
      for (int c = 0; c < channels; ++c) sat = sat || at(y, x, c) >= saturated_at;
      saturated += sat ? 1 : 0;
      const int ty = y / block, tx = x / block;
      if (ty >= thumb.rows || tx >= thumb.cols) continue;
      for (int c = 0; c < 3; ++c)
        sum[(static_cast<std::size_t>(ty) * thumb.cols + tx) * 3 + c] += at(y, x, channels == 1 ? 0 : c);
    }
  // Tone map: the frame is linear in exposure (the camera's raw codes), shown with the sRGB transfer curve.
  const double per_block = 1.0 / (static_cast<double>(block) * block * full);
  for (int y = 0; y < thumb.rows; ++y)
    for (int x = 0; x < thumb.cols; ++x)
      for (int c = 0; c < 3; ++c) {
        const double v = std::clamp(sum[(static_cast<std::size_t>(y) * thumb.cols + x) * 3 + c] * per_block, 0.0, 1.0);
        const double srgb = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
        thumb.ptr<uint8_t>(y)[x * 3 + c] = static_cast<uint8_t>(std::lround(srgb * 255.0));
      }
  auto png = encode_png(thumb);
  if (!png) return png.error();
  return nlohmann::json{{"width", frame.cols},
                        {"height", frame.rows},
                        {"bits", depth == CV_8U ? 8 : 16},
                        {"thumb_width", thumb.cols},
                        {"thumb_height", thumb.rows},
                        {"saturated_fraction", static_cast<double>(saturated) / (static_cast<double>(frame.total()))},
                        {"png_base64", base64(png.value())}};
}

}  // namespace vdrig::web

// A capture frame as the console's thumbnail: box-filtered to a small width, tone-mapped to 8-bit sRGB and encoded
// as PNG (base64, for a data: URL the page's Content-Security-Policy allows), with the frame's saturation.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "vdrig/core/result.hpp"

namespace vdrig::web {

constexpr int kThumbnailWidth = 240;

/// The fraction of pixels at which a channel is saturated: at or above this share of the frame's full scale.
constexpr double kSaturatedShare = 0.98;

/// From the PNG bytes of a frame (8 or 16 bit, grey or BGR, frames/view_VVVV_eEE.png): {"width", "height", "bits",
/// "thumb_width", "thumb_height", "saturated_fraction", "png_base64"}. kCorrupt naming `name` for bytes that are not
/// such an image.
Result<nlohmann::json> frame_thumbnail(std::string_view png_bytes, const std::string& name, int max_width);

std::string base64(std::string_view bytes);

}  // namespace vdrig::web

// JPEG encoding without chroma subsampling, for coefficient planes: OpenCV 4.6's encoder always subsamples the
// chroma 4:2:0, which mixes neighbouring texels' R, G and B coefficients (several codes of error where they differ).
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::rti {

/// An 8-bit BGR image as a baseline JPEG with 4:4:4 sampling at `quality` (1..100).
Result<std::string> encode_jpeg_444(const cv::Mat& bgr, int quality);

}  // namespace vdrig::rti

// Image bytes in memory: PNG, JPEG and TIFF decoded and encoded with libpng, libjpeg and libtiff directly
// (core/src/image_codec.cpp), not OpenCV's imgcodecs: Debian's imgcodecs links GDAL, GDCM, HDF5, Poppler... and costs
// every vdrig process ~0.15 s and 50 MB at start (issue #25). read_png / write_png (image_io.hpp) are built on these.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <string_view>

#include "vdrig/core/result.hpp"

namespace vdrig {

/// The pixel layout decode_image returns, named after the OpenCV flags whose results it reproduces.
enum class ImageDecode {
  kUnchanged,  // IMREAD_UNCHANGED: depth kept (8 or 16); grey 1 channel, colour BGR, alpha (or PNG tRNS) BGRA
  kBgr8,       // IMREAD_COLOR: always 8-bit BGR; grey repeated, alpha dropped, 16 bits cut to their high byte
};
/// Decodes PNG (libpng), JPEG (libjpeg) or TIFF (libtiff; the first image) bytes, told apart by their signature.
/// TIFF: 8- and 16-bit grey or RGB(A) strips as they are, other layouts 8-bit through libtiff's RGBA reader. EXIF
/// orientation is not applied (as IMREAD_UNCHANGED). Errors name `name`: kCorrupt for another format, corrupt or
/// truncated data (libjpeg's grey fill of a truncated JPEG included); kInvalidArgument for an image over read_png's
/// limits, before its pixels are allocated.
Result<cv::Mat> decode_image(std::string_view bytes, const std::string& name,
                             ImageDecode mode = ImageDecode::kUnchanged);

enum class PngCompression {
  kSmaller,  // zlib level 1, every row filter tried (write_png)
  kFastest,  // zlib level 1, SUB filter only: about twice as fast, files ~15% larger (capture's per-frame path)
};
/// Encodes an 8- or 16-bit image with 1, 3 (BGR) or 4 (BGRA) channels as PNG with libpng.
Result<std::string> encode_png(const cv::Mat& image, PngCompression compression = PngCompression::kSmaller);
/// Encodes an 8-bit grey or BGR image as a baseline JPEG with libjpeg's defaults (4:2:0 chroma, as OpenCV's
/// imencode) at `quality` 1..100.
Result<std::string> encode_jpeg(const cv::Mat& image, int quality);

}  // namespace vdrig

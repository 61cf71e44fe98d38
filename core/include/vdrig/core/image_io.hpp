// Image files: multi-channel OpenEXR (float or half, named channels, string/float attributes), PNG, JPEG, TIFF.
#pragma once

#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "vdrig/core/file_write.hpp"  // write_file_atomic: the writers here follow its protocol
#include "vdrig/core/result.hpp"

namespace vdrig {

/// A set of named float planes of equal size plus header attributes: the in-memory form of an OpenEXR file.
/// Channel names follow OpenEXR's layer convention ("kd.R", "sh.G.07", "mask").
struct ExrImage {
  int width = 0;
  int height = 0;
  std::vector<std::string> channel_names;  // in file order
  std::vector<cv::Mat> channels;           // CV_32FC1, height x width, same order as channel_names
  std::map<std::string, std::string> string_attributes;
  std::map<std::string, double> number_attributes;

  /// Index of a channel or -1.
  int find(const std::string& name) const;
  /// Adds a CV_32FC1 plane (size must match; the first plane sets the size).
  void add(const std::string& name, cv::Mat plane);
  /// Adds a colour image in OpenCV's order (CV_32FC3, planes B, G, R) as the channels "R", "G", "B": R is the
  /// third plane, B the first. The one place where vdrig turns a BGR cv::Mat into an RGB file (radiance, probes,
  /// cube maps, rendered frames); what `add` requires of a plane holds for each (abort otherwise).
  void add_bgr(const cv::Mat& bgr);
};

enum class ExrPixelType { kHalf, kFloat };

/// Writes to `path` atomically (a temporary file renamed into place).
Status write_exr(const std::filesystem::path& path, const ExrImage& image, ExrPixelType type = ExrPixelType::kFloat);
/// Reads every channel as float; a missing, truncated or non-EXR file (or one that is not a regular file) is an
/// error value, never an abort. When `max_bytes` is not 0, an image whose float planes would take more (width x
/// height x channels x 4 B, from the header) is kInvalidArgument before any pixel is allocated.
Result<ExrImage> read_exr(const std::filesystem::path& path, size_t max_bytes = 0);

/// Writes an 8- or 16-bit image (1, 3 or 4 channels, BGR(A) order for colour as OpenCV) atomically.
Status write_png(const std::filesystem::path& path, const cv::Mat& image);
/// Reads an 8- or 16-bit PNG or TIFF, or a JPEG, through decode_image, unchanged (depth kept). Errors: missing, not
/// a regular file, another format, corrupt or truncated (kCorrupt, naming the file), a file over 1 GiB, or an image
/// whose header states more than 16384 px a side or 100 Mpx (kInvalidArgument, refused before decoding; the largest
/// sensors vdrig drives are well inside).
Result<cv::Mat> read_png(const std::filesystem::path& path);

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

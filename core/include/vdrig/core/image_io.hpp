// Image files: multi-channel OpenEXR (float or half, named channels, string/float attributes), PNG, JPEG, TIFF.
#pragma once

#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <string>
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
/// Reads an 8- or 16-bit PNG or TIFF, or a JPEG, unchanged (decode_image, image_codec.hpp). Errors: missing, not a
/// regular file, another format, corrupt or truncated (kCorrupt, naming the file), a file over 1 GiB, or an image
/// over 16384 px a side or 100 Mpx by its header (kInvalidArgument, refused before decoding; sensors are well inside).
Result<cv::Mat> read_png(const std::filesystem::path& path);

}  // namespace vdrig

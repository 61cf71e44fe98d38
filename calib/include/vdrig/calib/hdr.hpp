// HDR merge of an exposure bracket to relative radiance, and the HdrImage type that carries the result
// between calib and fitting (stored as one OpenEXR file per view).
#pragma once

#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "vdrig/core/frame.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::calib {

/// Bit flags of HdrImage::mask (per pixel, OR-ed over the colour channels).
enum HdrMaskBits : uint8_t {
  kHdrValid = 0,
  kHdrSaturated = 1,  // some channel is at max code in EVERY exposure: value is a lower bound (from the shortest)
  kHdrBlack = 2,      // some channel is at code 0 in EVERY exposure: value is an upper bound (from the longest)
};

/// Relative radiance of one view, merged from a bracket.
///
/// - `radiance`: CV_32FC3, channels in OpenCV order (B, G, R) like the Frame it came from; the EXR file names them
///   R, G, B properly. Value = X / (exposure_s * gain), X being the response's relative exposure (X = 1 saturates
///   the sensor), so a value is "relative exposure per second at unit gain"; one scale for the whole session as
///   long as one response curve is used.
/// - `mask`: CV_8UC1 of HdrMaskBits (0 where at least one exposure saw the pixel unclipped in every channel).
/// - `exposures_s`, `gains`: the bracket that was merged, in input order (metadata, written to the EXR header).
/// - `bits`: significant bits of the input codes.
/// Channel order: Frames and `radiance` are B, G, R (OpenCV); ResponseCurve channels are R, G, B (as sim renders),
/// so image channel c goes through response channel 2 - c.
struct HdrImage {
  static constexpr int kFormatVersion = 1;

  cv::Mat radiance;
  cv::Mat mask;
  std::vector<double> exposures_s;
  std::vector<double> gains;
  int bits = 0;

  int width() const { return radiance.cols; }
  int height() const { return radiance.rows; }

  /// The EXR form: channels R, G, B, mask (mask as float 0..3); attributes vdrig.hdr.format_version,
  /// vdrig.hdr.bits, vdrig.hdr.exposures_s / vdrig.hdr.gains (comma-separated, %.9g).
  ExrImage to_exr() const;
  static Result<HdrImage> from_exr(const ExrImage& exr);
};

/// Writes an HdrImage as OpenEXR (half or float per the caller; the mask is exact in either) atomically.
Status write_hdr_exr(const std::filesystem::path& path, const HdrImage& image, ExrPixelType type = ExrPixelType::kHalf);
/// Reads an HdrImage written by write_hdr_exr (an EXR without a mask channel reads with an all-zero mask).
Result<HdrImage> read_hdr_exr(const std::filesystem::path& path);

/// Merge weight: the hat w(z) = min(z, max_code - z) / half, EXACTLY zero for the clipped codes 0 and max_code
/// (and above max_code, for 16-bit containers holding fewer significant bits).
float hdr_hat_weight(int code, int max_code);

/// Checks a bracket before merging or response recovery. Errors (kInvalidArgument, with the frame index):
/// no frames (or fewer than `min_frames`); empty image; type not CV_8UC3/CV_16UC3; sizes or types differing
/// between frames; bits out of range for the container (8-bit image with bits > 8, ...) or differing between frames;
/// exposure_s or gain missing (<= 0, NaN); two frames with the same effective exposure (exposure_s * gain);
/// effective exposures not sorted (strictly increasing or strictly decreasing); and, when `response` is not empty,
/// response bits differing from the frames' bits.
Status validate_bracket(std::span<const Frame> frames, const ResponseCurve& response, int min_frames = 1);

/// Merges a bracket of the same static scene into relative radiance: per pixel and channel
///   E = sum_j w(z_j) inverse(z_j) / t_j  /  sum_j w(z_j),   t_j = exposure_s_j * gain_j,
/// with w the hat above (clipped codes get no weight at all). Where every exposure is clipped in a channel the value
/// comes from the shortest exposure (all saturated, mask |= kHdrSaturated) or the longest one (all black, mask |=
/// kHdrBlack). An empty `response` means a linear (raw) camera: ResponseCurve::linear(frames' bits). Row-parallel
/// (cv::parallel_for_) over per-frame lookup tables indexed by code.
Result<HdrImage> merge_hdr(std::span<const Frame> frames, const ResponseCurve& response);

}  // namespace vdrig::calib

// Importing an RTI stack (photographs + .lp light list, light_positions.hpp) into an observation-map file
// (fitting/obsmap_file.hpp): RTI is vdrig's problem with light and view swapped, a fixed camera and one light
// direction per photograph shared by every pixel, so observation v of texel (s, t) is pixel (s, t) of image v and
// its direction is light v. The fits of fitting/ then run unchanged, and models linear in shared directions (PTM,
// SH, HSH) solve all texels with one operator (docs/rti.md).
//
// Frames: texel (s, t) is image column s and row H - 1 - t (counting the crop's rows), so that texel rows grow with
// y as docs/conventions.md wants and the .lp's direction (x right, y up in the image, z toward the camera) is the
// surface frame's. The map's size in mm is its size in pixels (RTI stacks carry no scale).
#pragma once

#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/rti/light_positions.hpp"

namespace vdrig::rti {

/// How 8- and 16-bit codes become the values that are fitted. Float images (EXR, 32-bit TIFF) pass unchanged.
///
/// The default fits the codes as they are (code / max): RTI viewers (RTIViewer, OpenLIME, relight) show the fitted
/// value as the display code, so a map of codes looks like the photographs there. kSrgb and kCurve fit linear
/// radiance instead (physically right sums of lights, and what vdrig's own renders of other maps hold); exported
/// to those viewers such a map shows darker mid-tones (docs/rti.md, "Colour").
struct Linearisation {
  enum class Kind { kCodes, kSrgb, kCurve };
  Kind kind = Kind::kCodes;
  ResponseCurve curve;  // kCurve: a recovered camera response (vdrig calib), its bits must be the images'

  /// "codes" (also "linear", its former name), "sRGB", or a response JSON file (as `vdrig calib` writes it);
  /// kInvalidArgument/kNotFound otherwise.
  static Result<Linearisation> parse(const std::string& text);
};

struct ImportOptions {
  std::optional<cv::Rect> crop;  // in image pixels (x, y from the top-left corner); must lie inside the images
  Linearisation linearisation;
  fitting::ObsFileOptions file;                       // tiles and compression of the observation map
  std::function<void(int done, int total)> on_image;  // progress, after each image
};

/// One stack image as linear RGB (CV_32FC3, channel order R G B, rows as in the file, cropped).
Result<cv::Mat> read_linear_image(const std::filesystem::path& path, const Linearisation& linearisation,
                                  const std::optional<cv::Rect>& crop);

/// What an import wrote.
struct ImportSummary {
  std::filesystem::path lp_file;
  int images = 0;
  int width = 0, height = 0;  // texels (the crop's size)
};

/// Imports the stack whose .lp is `stack` (or the single .lp in the folder `stack`) into the observation-map file
/// `out`, one image in memory at a time. Errors name the image: kNotFound for a missing image (checked for every
/// image before any is decoded), kInvalidArgument for an image whose size differs from the first's or a crop
/// outside the images, kCorrupt for an undecodable one; .lp errors as read_light_positions.
Result<ImportSummary> import_stack(const std::filesystem::path& stack, const std::filesystem::path& out,
                                   const ImportOptions& options = {});

}  // namespace vdrig::rti

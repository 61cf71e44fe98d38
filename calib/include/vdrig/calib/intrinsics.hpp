// Camera intrinsics from chessboard photographs (OpenCV's detector and Zhang's method via cv::calibrateCamera).
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::calib {

struct IntrinsicsOptions {
  /// Holds fx / fy at its initial value (1 unless the caller seeds it): what OpenCV's sample used for the reference
  /// left_intrinsics.yml. Off by default: a real sensor's pixels need not be square.
  bool fix_aspect_ratio = false;
  /// Holds k3 at 0 (CALIB_FIX_K3): with few views or a board that does not reach the image corners, k3 only trades
  /// off against k1 and k2 (OpenCV's tutorial advises fixing it for lenses of small distortion).
  bool fix_k3 = false;
  /// A view whose RMS reprojection error exceeds this multiple of the median view RMS is an outlier.
  double outlier_factor = 3.0;
  /// Calibrate again without the outlier views (the report keeps every view's error from the final fit).
  bool drop_outliers = false;
  /// cornerSubPix half window, pixels: 5 gives an 11x11 window. The window must stay within about half a square's
  /// image: one reaching the neighbouring corners biases the refined corners (docs/calib.md, Intrinsics).
  int subpix_half_window = 5;

  /// Largest subpix_half_window (a 129 x 129 window); the images must also be larger than the window (see
  /// calibrate_intrinsics).
  static constexpr int kMaxSubpixHalfWindow = 64;
  /// False with the reason for an outlier factor not above 1 or a half window outside [1, kMaxSubpixHalfWindow].
  bool is_valid(std::string* why = nullptr) const;
};

/// One input image's part in the calibration.
struct IntrinsicsView {
  size_t image_index = 0;
  bool board_found = false;
  bool used = false;     // in the final fit (found, and not dropped as an outlier)
  bool outlier = false;  // rms_px > outlier_factor * median
  double rms_px = 0.0;   // RMS reprojection error of this view's corners with the final model
  ViewPose pose;         // board frame -> camera, t in millimetres (board origin at its first inner corner)
};

/// One standard deviation of each estimated parameter (from calibrateCamera's stdDeviationsIntrinsics); zero for
/// a parameter held fixed, except fx under fix_aspect_ratio, which carries fy's (scaled by fx / fy).
struct IntrinsicsStdDev {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
};

struct IntrinsicsResult {
  CameraModel camera;
  IntrinsicsStdDev std_dev;
  double rms_px = 0.0;  // overall RMS reprojection error of the final fit (calibrateCamera's return value)
  std::vector<IntrinsicsView> views;  // one per input image, input order
  int board_cols = 0, board_rows = 0;
  double square_m = 0.0;
  bool fix_aspect_ratio = false;
  bool fix_k3 = false;

  size_t used_views() const;
  /// Writes OpenCV-compatible YAML through CameraModel::save_yaml (camera_matrix, distortion_coefficients,
  /// image_width/height, avg_reprojection_error) with, in the same map, the calibration record OpenCV's sample writes:
  /// nframes, board_width/height, square_size, flags, per_view_reprojection_errors, plus vdrig's
  /// std_dev_intrinsics (fx fy cx cy k1 k2 p1 p2 k3) and view_indices/outlier_views.
  Status save_yaml(const std::filesystem::path& path) const;
};

/// Finds the inner corners of a `board_cols` x `board_rows` chessboard (cv::findChessboardCorners, refined by
/// cv::cornerSubPix) in every image (8-bit, grey or BGR, all the same size) and fits the full Brown-Conrady model
/// (k1, k2, p1, p2, k3) with cv::calibrateCamera (the overload reporting standard deviations and per-view errors).
/// Errors: kInvalidArgument for invalid options, no images, bad board or square size, differing image sizes,
/// unsupported types, images too small for the board and the corner window (each side at least
/// max(2 subpix_half_window + 5, 4 (corners + 1)) pixels), or fewer than 3 views with the board found.
Result<IntrinsicsResult> calibrate_intrinsics(std::span<const cv::Mat> images, int board_cols, int board_rows,
                                              double square_m, const IntrinsicsOptions& options = {});

}  // namespace vdrig::calib

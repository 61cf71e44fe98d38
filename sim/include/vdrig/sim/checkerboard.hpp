// A simulated checkerboard target for intrinsics calibration: a flat board in its own surface frame (origin at the
// board centre, x along the columns, y along the rows, z toward the camera side, mm), rendered through the same
// camera model (pinhole + Brown-Conrady) and pose convention (p_cam = R p_board + t) as the rig's surface.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {

struct CheckerboardSpec {
  int cols = 9;  // squares across (x); OpenCV's pattern size is (cols - 1) x (rows - 1) inner corners
  int rows = 7;  // squares down (y)
  double square_mm = 30.0;
  double margin_mm = 30.0;  // white border around the squares (corner detection needs one)
  double white = 0.85;      // albedo of the white squares and the margin
  double black = 0.04;      // albedo of the black squares

  bool is_valid(std::string* why) const;
};

/// The board as a Scene lit evenly (ambient 1, no point light), so a pixel's radiance is the albedo it sees.
/// The square at the (-x, -y) corner is black.
Scene checkerboard_scene(const CheckerboardSpec& spec);

/// Inner corners in the board frame (z = 0), row-major from the (-x, -y) corner: (cols - 1) x (rows - 1) points.
std::vector<Vec3d> checkerboard_corners_mm(const CheckerboardSpec& spec);

/// An 8-bit grey photograph of the board: radiance (green channel) mapped linearly to codes (albedo 1 -> 255),
/// samples_per_axis^2 rays per pixel. Pixels off the board are 0.
cv::Mat render_checkerboard(const CheckerboardSpec& spec, const CameraModel& camera, const ViewPose& pose,
                            int samples_per_axis = 4);

}  // namespace vdrig::sim

// The simulated checkerboard target: OpenCV's detector finds it, and its refined corners are where the camera model
// projects the board's corners.
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "vdrig/sim/checkerboard.hpp"

namespace vdrig::sim {
namespace {

/// A board pose: camera on the board's +z side at `distance_mm`, the board turned by `rvec` (Rodrigues, radians).
ViewPose board_pose(const Vec3d& rvec, const Vec3d& shift_mm, double distance_mm) {
  const Mat3d flip = Vec3d(1, -1, -1).asDiagonal();  // camera looks down at the board's +z side
  const Mat3d R = flip * Eigen::AngleAxisd(rvec.norm(), rvec.normalized()).toRotationMatrix();
  return {R, Vec3d(0, 0, distance_mm) + shift_mm};
}

TEST(Checkerboard, DetectedCornersMatchProjections) {
  const CheckerboardSpec spec;  // 9 x 7 squares of 30 mm
  const CameraModel cam{480, 360, 560.0, 565.0, 241.7, 178.4, -0.08, 0.02, 0.0005, -0.0003, 0.0};
  const auto corners = checkerboard_corners_mm(spec);
  ASSERT_EQ(corners.size(), static_cast<size_t>((spec.cols - 1) * (spec.rows - 1)));
  double worst = 0;
  for (const ViewPose& pose :
       {board_pose({0.05, 0.02, 0.1}, {10, -5, 0}, 650), board_pose({0.45, -0.25, 0.3}, {-20, 15, 0}, 700)}) {
    const cv::Mat img = render_checkerboard(spec, cam, pose, 4);
    std::vector<cv::Point2f> found;
    Vec2d mean_err = Vec2d::Zero();
    ASSERT_TRUE(cv::findChessboardCorners(img, cv::Size(spec.cols - 1, spec.rows - 1), found,
                                          cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE));
    cv::cornerSubPix(img, found, cv::Size(8, 8), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
    ASSERT_EQ(found.size(), corners.size());
    for (const cv::Point2f& f : found) {
      double nearest = 1e9;
      Vec2d dv = Vec2d::Zero();
      for (const Vec3d& c : corners) {
        const Vec2d d = Vec2d(f.x, f.y) - cam.project(pose.to_camera(c));
        if (d.norm() < nearest) nearest = d.norm(), dv = d;
      }
      mean_err += dv / found.size();
      worst = std::max(worst, nearest);
    }
    std::printf("checkerboard view: mean corner error (%.4f, %.4f) px\n", mean_err.x(), mean_err.y());
    EXPECT_LT(mean_err.norm(), 0.02);  // no systematic offset (pixel-centre convention)
  }
  std::printf("checkerboard: worst corner %.4f px from its projection\n", worst);
  EXPECT_LT(worst, 0.1);
}

TEST(Checkerboard, BoardHasAWhiteMarginAndBlackCornerSquare) {
  const CheckerboardSpec spec;
  const Scene s = checkerboard_scene(spec);
  const double x0 = -spec.cols * spec.square_mm / 2, y0 = -spec.rows * spec.square_mm / 2;
  EXPECT_NEAR(s.radiance({x0 + 5, y0 + 5, 0}, Vec3d::UnitZ()).x(), spec.black, 1e-12);
  EXPECT_NEAR(s.radiance({x0 + 35, y0 + 5, 0}, Vec3d::UnitZ()).x(), spec.white, 1e-12);
  EXPECT_NEAR(s.radiance({x0 - 5, y0 + 5, 0}, Vec3d::UnitZ()).x(), spec.white, 1e-12);
  EXPECT_EQ(s.material_at(x0 - spec.margin_mm - 1, 0), -1);
}

}  // namespace
}  // namespace vdrig::sim

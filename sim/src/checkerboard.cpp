#include "vdrig/sim/checkerboard.hpp"

#include "vdrig/sim/renderer.hpp"

namespace vdrig::sim {

bool CheckerboardSpec::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = "checkerboard: " + m;
    return false;
  };
  if (cols < 3 || rows < 3) return fail("needs at least 3 x 3 squares");
  if (!(square_mm > 0) || !(margin_mm >= 0)) return fail("square size must be > 0 and margin >= 0");
  if (!(white > black) || black < 0) return fail("white must be brighter than black");
  return true;
}

Scene checkerboard_scene(const CheckerboardSpec& spec) {
  std::string why;
  VDRIG_CHECK(spec.is_valid(&why), why);
  Scene s;
  s.name = "checkerboard";
  s.width_mm = spec.cols * spec.square_mm + 2 * spec.margin_mm;
  s.height_mm = spec.rows * spec.square_mm + 2 * spec.margin_mm;
  s.materials = {{"white", Vec3d::Constant(spec.white), Vec3d::Zero(), 1.0},
                 {"black", Vec3d::Constant(spec.black), Vec3d::Zero(), 1.0}};
  const double x0 = -spec.cols * spec.square_mm / 2.0, y0 = -spec.rows * spec.square_mm / 2.0;
  for (int r = 0; r < spec.rows; ++r)
    for (int c = 0; c < spec.cols; ++c)
      if ((r + c) % 2 == 0)
        s.patches.push_back({x0 + c * spec.square_mm, y0 + r * spec.square_mm, x0 + (c + 1) * spec.square_mm,
                             y0 + (r + 1) * spec.square_mm, 1});
  s.ambient = Vec3d::Ones();
  return s;
}

std::vector<Vec3d> checkerboard_corners_mm(const CheckerboardSpec& spec) {
  std::vector<Vec3d> out;
  const double x0 = -spec.cols * spec.square_mm / 2.0, y0 = -spec.rows * spec.square_mm / 2.0;
  for (int r = 1; r < spec.rows; ++r)
    for (int c = 1; c < spec.cols; ++c) out.emplace_back(x0 + c * spec.square_mm, y0 + r * spec.square_mm, 0.0);
  return out;
}

cv::Mat render_checkerboard(const CheckerboardSpec& spec, const CameraModel& camera, const ViewPose& pose,
                            int samples_per_axis) {
  const cv::Mat radiance = render_radiance(checkerboard_scene(spec), camera, pose, samples_per_axis);
  cv::Mat green, out;
  cv::extractChannel(radiance, green, 1);
  green.convertTo(out, CV_8U, 255.0);  // saturate_cast rounds and clips
  return out;
}

}  // namespace vdrig::sim

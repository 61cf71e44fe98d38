#include "vdrig/pipeline/render_stage.hpp"

#include "surface_rays.hpp"

namespace vdrig::pipeline {

cv::Mat surface_region_mask(const CameraModel& camera, const ViewPose& pose, double x0, double y0, double x1,
                            double y1) {
  cv::Mat mask(camera.height, camera.width, CV_8UC1, cv::Scalar(0));
  for_each_surface_hit(camera, pose, [&](int x, int y, const Vec3d& p) {
    if (p.x() >= x0 && p.x() <= x1 && p.y() >= y0 && p.y() <= y1) mask.at<uint8_t>(y, x) = 255;
  });
  return mask;
}

}  // namespace vdrig::pipeline

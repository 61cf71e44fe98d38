#include "vdrig/pipeline/render_stage.hpp"

#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "surface_rays.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/pipeline/hdr_stage.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

Result<Comparison> render_and_compare(const capture::Session& session, const fitting::ParameterMap& map, int view,
                                      const fs::path& out_dir, const cv::Mat& region) {
  auto geometry = session_geometry(session);
  if (!geometry) return geometry.error();
  const auto frames = session.frames_of_view(view);
  if (frames.empty()) return make_error(ErrorCode::kNotFound, "view " + std::to_string(view) + " has no frames");
  auto response = session_response(session);
  if (!response) return response.error();
  // Compare in the camera's own units with the middle exposure of the bracket (well exposed on most of the surface).
  const capture::FrameRecord& rec = frames[frames.size() / 2];
  auto photo = session.load_image(rec);
  if (!photo) return photo.error();

  auto ctx = viewer::GlContext::create(geometry->camera.width, geometry->camera.height, false);
  if (!ctx) return ctx.error();
  auto renderer = viewer::SurfaceRenderer::create(map);
  if (!renderer) return renderer.error();
  auto radiance = renderer.value()->render_radiance(geometry->camera, geometry->poses.at(view), {});
  if (!radiance) return radiance.error();
  const cv::Mat render = viewer::to_camera_codes(radiance.value(), rec.exposure_s, rec.gain, response.value());

  cv::Mat diff;
  cv::absdiff(render, photo.value(), diff);
  cv::Mat diff_f;
  diff.convertTo(diff_f, CV_32F);
  const cv::Mat mask = region.empty() ? cv::Mat(diff.size(), CV_8U, cv::Scalar(255)) : region;
  const cv::Scalar mean = cv::mean(diff_f, mask);
  Comparison c;
  c.mean_abs_error = (mean[0] + mean[1] + mean[2]) / 3.0;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  char stem[32];
  std::snprintf(stem, sizeof stem, "view_%04d", view);
  c.render_png = out_dir / (std::string(stem) + "_render.png");
  c.photo_png = out_dir / (std::string(stem) + "_photo.png");
  c.diff_png = out_dir / (std::string(stem) + "_diff_x8.png");
  cv::Mat diff_vis;
  diff.convertTo(diff_vis, CV_8U, 8.0);  // amplified 8x so small differences are visible
  VDRIG_TRY(write_png(c.render_png, render));
  VDRIG_TRY(write_png(c.photo_png, photo.value()));
  VDRIG_TRY(write_png(c.diff_png, diff_vis));
  return c;
}

cv::Mat surface_region_mask(const CameraModel& camera, const ViewPose& pose, double x0, double y0, double x1,
                            double y1) {
  cv::Mat mask(camera.height, camera.width, CV_8UC1, cv::Scalar(0));
  for_each_surface_hit(camera, pose, [&](int x, int y, const Vec3d& p) {
    if (p.x() >= x0 && p.x() <= x1 && p.y() >= y0 && p.y() <= y1) mask.at<uint8_t>(y, x) = 255;
  });
  return mask;
}

}  // namespace vdrig::pipeline

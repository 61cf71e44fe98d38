#include "vdrig/viewer/headless.hpp"

#include <algorithm>
#include <cctype>

namespace vdrig::viewer {

Result<cv::Mat> render_map_radiance(const fitting::ParameterMap& map, const CameraModel& camera, const ViewPose& pose,
                                    const RenderSettings& settings) {
  std::string why;
  if (!camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "camera: " + why);
  if (settings.samples_per_axis < 1 || settings.samples_per_axis > 8)
    return make_error(ErrorCode::kInvalidArgument, "samples_per_axis must be in [1, 8]");
  auto ctx = GlContext::create(camera.width, camera.height, false);
  if (!ctx) return ctx.error();
  auto renderer = SurfaceRenderer::create(map);
  if (!renderer) return renderer.error();
  return renderer.value()->render_radiance(camera, pose, settings);
}

Status write_frame(const std::filesystem::path& path, const cv::Mat& radiance_bgr, double gamma) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".exr") {
    ExrImage exr;
    exr.add_bgr(radiance_bgr);
    return write_exr(path, exr);
  }
  if (ext == ".png") return write_png(path, tone_map(radiance_bgr, gamma));
  return make_error(ErrorCode::kInvalidArgument,
                    "--out must end in .png (tone mapped) or .exr (linear radiance): " + path.string());
}

}  // namespace vdrig::viewer

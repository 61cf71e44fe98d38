// Headless renders of a parameter map: one frame through the viewer's shader (SurfaceRenderer) in an invisible
// OpenGL context, as `vdrig render` writes it (tone-mapped PNG or linear-radiance EXR).
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::viewer {

/// Linear radiance (CV_32FC3, BGR, camera.width x camera.height) of `map` seen by `camera` from `pose`, rendered in
/// an invisible window of its own (GlContext: kUnsupported without a display; xvfb-run in CI).
Result<cv::Mat> render_map_radiance(const fitting::ParameterMap& map, const CameraModel& camera, const ViewPose& pose,
                                    const RenderSettings& settings = {});

/// Writes a frame by the file's extension: ".exr" linear radiance in channels R, G, B (ExrImage::add_bgr; the map's
/// units), ".png" tone mapped
/// (tone_map(radiance, gamma)); any other extension is kInvalidArgument.
Status write_frame(const std::filesystem::path& path, const cv::Mat& radiance_bgr, double gamma);

}  // namespace vdrig::viewer

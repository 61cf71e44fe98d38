// Render stage: a parameter map rendered from a captured view's pose and compared with that view's photograph.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "vdrig/capture/session.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::pipeline {

/// Renders the map from a session view's pose; writes render, photograph and |difference| PNGs to out_dir (the
/// session's renders folder, capture::SessionLayout::renders_dir, or any other) and returns the mean absolute
/// difference in 8-bit code units over `region` (non-zero pixels), or all pixels.
struct Comparison {
  double mean_abs_error = 0;
  std::filesystem::path render_png, photo_png, diff_png;
};
Result<Comparison> render_and_compare(const capture::Session& session, const fitting::ParameterMap& map, int view,
                                      const std::filesystem::path& out_dir, const cv::Mat& region = {});

/// Pixels (CV_8UC1, 255) whose ray meets the surface inside the rectangle [x0, x1] x [y0, y1] mm (surface frame).
cv::Mat surface_region_mask(const CameraModel& camera, const ViewPose& pose, double x0_mm, double y0_mm, double x1_mm,
                            double y1_mm);

}  // namespace vdrig::pipeline

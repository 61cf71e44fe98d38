// Render stage helpers. Renders are compared with photographs in one place, compare_stage.hpp (`vdrig compare`, which
// `vdrig demo` calls too); here what a caller needs to restrict that comparison to a part of the surface.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "vdrig/capture/session.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::pipeline {

/// Pixels (CV_8UC1, 255) whose ray meets the surface inside the rectangle [x0, x1] x [y0, y1] mm (surface frame).
cv::Mat surface_region_mask(const CameraModel& camera, const ViewPose& pose, double x0_mm, double y0_mm, double x1_mm,
                            double y1_mm);

}  // namespace vdrig::pipeline

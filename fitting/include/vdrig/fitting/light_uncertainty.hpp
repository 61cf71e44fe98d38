// How well estimate_point_lights (lights.hpp) located a point light: the covariance of its position from the angular
// residuals of its inlier rays (Gauss-Newton: sigma^2 (J^T W J)^-1, sigma^2 the weighted residual variance per ray
// component). It treats the rays as independent, which neighbouring texels' lobes are not (they share the fit's
// biases), so it is a lower bound on the error: docs/models.md ("The light") has how it compares with the truth.
#pragma once

#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/lights.hpp"

namespace vdrig::fitting {

/// The position covariance (mm^2, surface frame) of `light`, one of estimate_point_lights(rays, options)'s, over the
/// rays it explains (within options.inlier_angle_rad). kInvalidArgument for a light at infinity (its direction has
/// no position) or fewer than 2 inlier rays.
Result<Mat3d> light_position_covariance(const std::vector<LobeRay>& rays, const EstimatedLight& light,
                                        const LightEstimationOptions& options);

}  // namespace vdrig::fitting

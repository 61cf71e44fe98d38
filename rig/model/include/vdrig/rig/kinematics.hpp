// Kinematics of the pan/tilt rig: which pan/tilt puts the camera in a given direction over the surface.
//
// World frame: origin where the pan axis meets the tilt axis (the surface centre on an ideal rig), +z toward the
// fixed camera, +x horizontal (the tilt axis), +y up. The camera sits at (0, 0, camera_distance_mm) looking down -z,
// image x along world +x, image y along world -y, so p_cam = R_cam_world (p_world - C) with R_cam_world =
// diag(1, -1, -1).
//
// The stage reports encoder readings (pan_r, tilt_r); the axes' true angles are pan = pan_r - pan_zero and
// tilt = tilt_r - tilt_zero. The platter (the part that turns with pan) is posed in the world by
//     R_world_platter = Rx(tilt) * Rz(pan):  pan about the platter's axis first, then tilt about world x,
// and the surface sits on the platter at p_platter = A p_surface + surface_offset, A = Rx(axis_tilt_x) Ry(axis_tilt_y)
// (the pan axis is not exactly the surface normal). So
//     R_world_surface = Rx(tilt_r - tilt_zero) Rz(pan_r - pan_zero) A,   p_world = R_world_platter (A p + offset).
// On an ideal rig (every parameter but the distance zero) that is Rx(tilt_r) Rz(pan_r), and the view direction
// (surface centre -> camera) in the surface frame is
//     v = Rz(-pan) Rx(-tilt) e_z = (sin tilt sin pan, sin tilt cos pan, cos tilt),
// i.e. zenith = tilt and azimuth = pi/2 - pan. The model is written once, over any scalar type, in
// kinematics_model.hpp (the calibration differentiates it).
#pragma once

#include <optional>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/rig/stage_spec.hpp"

namespace vdrig::rig {

/// Geometry of a rig (see the model above). Every parameter defaults to an ideal rig, so a calibration file that
/// lacks the newer ones reads as the ideal rig it was fitted as.
///  - camera_distance_mm: from the axes' crossing to the camera centre.
///  - surface_offset_mm: the surface-frame origin in the platter frame (it turns with pan, then tilt).
///  - pan_zero_rad, tilt_zero_rad: the encoder reading at the axis' true zero (reading = true angle + zero). The true
///    pan zero puts surface +x along the tilt axis (so it also absorbs a surface mounted turned on the platter); the
///    true tilt zero puts the pan axis on the camera's line of sight.
///  - pan_axis_tilt_x_rad, pan_axis_tilt_y_rad: the surface frame turned in the platter frame by A = Rx(x) Ry(y).
///    Seen from the surface the pan axis is then A^T e_z = (-cos x sin y, sin x, cos x cos y) ~ (-y, x, 1): a
///    platter not square to its axis, or a sample not flat on it. (A misalignment of the pan axis against the tilt
///    axis, the fifth rotational degree of freedom, is not modelled.)
struct RigGeometry {
  double camera_distance_mm = 2500.0;
  Vec3d surface_offset_mm = Vec3d::Zero();
  double pan_zero_rad = 0.0;
  double tilt_zero_rad = 0.0;
  double pan_axis_tilt_x_rad = 0.0;
  double pan_axis_tilt_y_rad = 0.0;
};

/// Rotation of the platter in the world frame, Rx(tilt) Rz(pan), for true axis angles (an ideal rig's readings).
Mat3d platform_rotation(const PanTilt& pt);

/// Pose of the surface in the camera (p_cam = R p_surface + t) for a pan/tilt position (encoder readings).
ViewPose surface_pose(const RigGeometry& geometry, const PanTilt& pt);

/// Direction from the surface origin toward the camera, in the surface frame (forward kinematics).
Vec3d view_direction(const RigGeometry& geometry, const PanTilt& pt);

/// Inverse kinematics: the pan/tilt readings that look at the surface origin from `direction` (unit, surface frame),
/// within the stage's axis limits (which bound readings); nullopt when no reachable position gives it. At the pole
/// (zenith ~ 0) pan is free and `preferred_pan_rad` is kept; elsewhere, of the whole-turn equivalents of the pan
/// within the limits, the one nearest `preferred_pan_rad` is returned. Exact (closed form) for the whole model:
/// view_direction(geometry, result) == direction to rounding.
std::optional<PanTilt> inverse_kinematics(const RigGeometry& geometry, const StageSpec& spec, const Vec3d& direction,
                                          double preferred_pan_rad = 0.0);

}  // namespace vdrig::rig

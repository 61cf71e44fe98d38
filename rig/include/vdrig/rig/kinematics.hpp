// Kinematics of the pan/tilt rig: which pan/tilt puts the camera in a given direction over the surface.
//
// World frame: origin where the pan axis meets the tilt axis (the surface centre on an ideal rig), +z toward the
// fixed camera, +x horizontal (the tilt axis), +y up. The platform (surface and its lights) turns as
//     R_world_surface = Rx(tilt) * Rz(pan):  pan about the surface normal first, then tilt about world x.
// The camera sits at (0, 0, camera_distance_mm) looking down -z, image x along world +x, image y along world -y,
// so p_cam = R_cam_world (p_world - C) with R_cam_world = diag(1, -1, -1).
//
// The view direction (surface centre -> camera) in the surface frame is then
//     v = Rz(-pan) Rx(-tilt) e_z = (sin tilt sin pan, sin tilt cos pan, cos tilt),
// i.e. zenith = tilt and azimuth = pi/2 - pan.
#pragma once

#include <optional>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

/// Geometry of a rig. `surface_offset_mm` is the surface-frame origin in the platform frame (zero on an ideal rig,
/// non-zero when the surface is not centred on the axes: the simulator and the kinematic calibration use it).
struct RigGeometry {
  double camera_distance_mm = 2500.0;
  Vec3d surface_offset_mm = Vec3d::Zero();
};

/// Rotation of the platform in the world frame for a pan/tilt position.
Mat3d platform_rotation(const PanTilt& pt);

/// Pose of the surface in the camera (p_cam = R p_surface + t) for a pan/tilt position.
ViewPose surface_pose(const RigGeometry& geometry, const PanTilt& pt);

/// Direction from the surface origin toward the camera, in the surface frame (forward kinematics).
Vec3d view_direction(const RigGeometry& geometry, const PanTilt& pt);

/// Inverse kinematics: the pan/tilt that looks at the surface origin from `direction` (unit, surface frame),
/// within the stage's axis limits; nullopt when no reachable position gives it. At the pole (zenith ~ 0) pan is
/// free and `preferred_pan_rad` is kept; elsewhere, of the whole-turn equivalents of the pan within the limits,
/// the one nearest `preferred_pan_rad` is returned. Exact (closed form) on an ideal rig and with a surface offset,
/// where the direction is the one to the surface origin.
std::optional<PanTilt> inverse_kinematics(const RigGeometry& geometry, const StageSpec& spec, const Vec3d& direction,
                                          double preferred_pan_rad = 0.0);

}  // namespace vdrig::rig

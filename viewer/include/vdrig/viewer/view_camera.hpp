// ViewCamera: where the interactive viewer looks from. Pure logic (no OpenGL), so every rule below is unit-tested
// (tests/viewer/test_view_camera.cpp); the window loop (interactive.hpp) only feeds it input.
//
// Two modes:
//  - Free: an orbit around a target on the surface plane (the surface centre unless panned). The camera centre is
//      C = target + distance * d(azimuth, zenith),  d = (sin zen cos az, sin zen sin az, cos zen)  (surface frame),
//    it looks at the target, and its image axes are the spherical tangent vectors at d:
//      image x (right) = e_az  = (-sin az, cos az, 0),
//      image y (down)  = e_zen = (cos zen cos az, cos zen sin az, -sin zen),
//    so 'up' in the image points toward the surface normal (the far edge of the surface is at the top), the frame
//    turns smoothly with azimuth (no flip at the 0/2pi wrap) and stays defined at zenith 0 (no look-at with a fixed
//    up vector, whose cross product vanishes there). Zenith is clamped to [0, max_zenith] (89 degrees), the distance
//    to [min_distance, max_distance].
//    At azimuth 3pi/2 and zenith 0 (the reset view) image x = surface +x and image y = surface -y.
//  - Constrained: the camera sits exactly at one of the session's captured view poses (as calibrated: the pose
//    the photograph was taken from, with the rig's own image roll), so a rendering can be put beside the photo.
//
// Dragging moves the camera opposite to the drag in the image ("grab the scene"): in free mode a drag right
// decreases the azimuth, a drag down decreases the zenith; in constrained mode a drag of at least drag_step_px
// moves to the nearest captured view lying in that direction (neighbour_view).
#pragma once

#include <vector>

#include "vdrig/core/camera.hpp"

namespace vdrig::viewer {

struct ViewCameraSettings {
  double max_zenith_rad = 89.0 * kPi / 180.0;
  double min_distance_mm = 100.0;
  double max_distance_mm = 50000.0;
  double rad_per_px = 0.005;            // free orbit: angle per pixel of drag
  double zoom_per_step = 0.9;           // distance factor per scroll step (scroll up = closer)
  double drag_step_px = 30.0;           // constrained: accumulated drag that moves to a neighbouring view
  double neighbour_cone_rad = kPi / 3;  // constrained: half-angle of the directions counted as "that way"
};

/// Pose of a camera at target + distance * d(azimuth, zenith) looking at `target`, image axes as described above.
ViewPose orbit_pose(const Vec3d& target_mm, double azimuth_rad, double zenith_rad, double distance_mm);

class ViewCamera {
 public:
  enum class Mode { kFree, kConstrained };

  /// Free mode at the reset view: azimuth 3pi/2, zenith 0, `distance_mm` (clamped), target at the surface centre.
  explicit ViewCamera(double distance_mm = 2500.0, const ViewCameraSettings& settings = {});

  const ViewCameraSettings& settings() const { return settings_; }

  // --- Free orbit (kept while constrained, so toggling back returns to it unless changed) ---
  /// Sets the orbit; azimuth is wrapped into [0, 2pi), zenith and distance clamped.
  void set_orbit(double azimuth_rad, double zenith_rad, double distance_mm);
  double azimuth_rad() const { return azimuth_rad_; }
  double zenith_rad() const { return zenith_rad_; }
  double distance_mm() const { return distance_mm_; }
  const Vec3d& target_mm() const { return target_mm_; }
  /// Moves the target by an image-plane displacement (mm, along the free camera's image x and y) projected onto
  /// the surface plane, grabbing the scene: the surface follows the displacement.
  void pan_by(const Vec2d& image_mm);
  /// Unit direction from the target toward the free camera.
  Vec3d free_direction() const { return direction_from_spherical(azimuth_rad_, zenith_rad_); }

  // --- Captured views ---
  /// The session's view poses (p_cam = R p_surface + t). Resets the current view to 0 and, when empty, the mode
  /// to free.
  void set_captured_views(std::vector<ViewPose> poses);
  const std::vector<ViewPose>& captured_views() const { return captured_; }
  int captured_count() const { return static_cast<int>(captured_.size()); }
  /// Unit direction from the surface centre toward captured view k's camera centre.
  Vec3d captured_direction(int k) const;
  /// The captured view whose direction makes the smallest angle with `direction` (unit); -1 when there is none.
  int nearest_view(const Vec3d& direction) const;
  /// The captured view the camera reaches by moving from view `from` in image direction `camera_motion` (x right,
  /// y down, in view `from`'s image): among the views whose great-circle direction from `from` deviates by less than
  /// neighbour_cone_rad from that motion, the one minimising angle / cos(deviation) (near, and straight that way);
  /// -1 when none lies that way.
  int neighbour_view(int from, const Vec2d& camera_motion) const;

  // --- Mode and stepping ---
  Mode mode() const { return mode_; }
  /// Constrained mode needs captured views (returns false and stays free without). Entering it snaps to the view
  /// nearest the free camera; leaving it puts the free orbit at the current view (its direction and distance, as
  /// seen from the surface centre; the image roll becomes the free one).
  bool set_mode(Mode mode);
  bool toggle_mode() { return set_mode(mode_ == Mode::kFree ? Mode::kConstrained : Mode::kFree); }
  /// Index of the captured view shown (constrained) or last shown (free); -1 without captured views.
  int current_view() const { return captured_.empty() ? -1 : current_view_; }
  /// Shows captured view k (wrapped modulo the count) in constrained mode.
  void select_view(int k);
  /// Next (+1) / previous (-1) captured view from the current one, wrapping around; enters constrained mode.
  void step(int delta) { select_view(current_view_ + delta); }
  /// Constrained mode at the captured view nearest the free camera's direction; returns it (-1: none, stays free).
  int snap();

  // --- Input (pixels of the window) ---
  /// Mouse drag by (dx, dy) pixels, x right, y down. Free: orbit. Constrained: accumulates, and each time the
  /// accumulated drag reaches drag_step_px moves to neighbour_view in the opposite direction (camera motion).
  void drag(double dx_px, double dy_px);
  /// Button released: forgets a partial constrained drag.
  void end_drag() { drag_accum_px_ = Vec2d::Zero(); }
  /// Scroll by `steps` (positive = away from the user = closer): distance *= zoom_per_step^steps (free mode only;
  /// a captured view's pose is what the photograph saw).
  void scroll(double steps);
  /// Free mode at the reset view, with the constructor's distance; current view 0.
  void reset();

  /// The pose to render: the free orbit, or the current captured view.
  ViewPose pose() const;

 private:
  ViewCameraSettings settings_;
  double initial_distance_mm_;
  double azimuth_rad_ = 0, zenith_rad_ = 0, distance_mm_ = 0;
  Vec3d target_mm_ = Vec3d::Zero();
  std::vector<ViewPose> captured_;
  int current_view_ = 0;
  Mode mode_ = Mode::kFree;
  Vec2d drag_accum_px_ = Vec2d::Zero();
};

}  // namespace vdrig::viewer

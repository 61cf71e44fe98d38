#include "vdrig/viewer/view_camera.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "vdrig/core/result.hpp"

namespace vdrig::viewer {
namespace {

double wrap_azimuth(double a) {
  a = std::fmod(a, 2.0 * kPi);
  if (a < 0) a += 2.0 * kPi;
  // fmod of a value just below 0 can round to exactly 2pi.
  return a >= 2.0 * kPi ? 0.0 : a;
}

}  // namespace

ViewPose orbit_pose(const Vec3d& target, double azimuth_rad, double zenith_rad, double distance_mm) {
  const double ca = std::cos(azimuth_rad), sa = std::sin(azimuth_rad);
  const double cz = std::cos(zenith_rad), sz = std::sin(zenith_rad);
  const Vec3d d(sz * ca, sz * sa, cz);
  const Vec3d x(-sa, ca, 0.0);           // e_az
  const Vec3d y(cz * ca, cz * sa, -sz);  // e_zen
  const Vec3d z = -d;                    // optical axis toward the target; (x, y, z) right-handed: e_az x e_zen = -d
  ViewPose pose;
  pose.R.row(0) = x.transpose();
  pose.R.row(1) = y.transpose();
  pose.R.row(2) = z.transpose();
  const Vec3d centre = target + distance_mm * d;
  pose.t = -pose.R * centre;
  return pose;
}

ViewCamera::ViewCamera(double distance_mm, const ViewCameraSettings& settings)
    : settings_(settings), initial_distance_mm_(distance_mm) {
  VDRIG_CHECK(settings_.min_distance_mm > 0 && settings_.max_distance_mm >= settings_.min_distance_mm,
              "ViewCamera distance range must be positive and ordered");
  reset();
}

void ViewCamera::set_orbit(double azimuth_rad, double zenith_rad, double distance_mm) {
  azimuth_rad_ = wrap_azimuth(azimuth_rad);
  zenith_rad_ = std::clamp(zenith_rad, 0.0, settings_.max_zenith_rad);
  distance_mm_ = std::clamp(distance_mm, settings_.min_distance_mm, settings_.max_distance_mm);
}

void ViewCamera::pan_by(const Vec2d& image_mm) {
  const ViewPose p = orbit_pose(Vec3d::Zero(), azimuth_rad_, zenith_rad_, 1.0);
  Vec3d move = image_mm.x() * p.R.row(0).transpose() + image_mm.y() * p.R.row(1).transpose();
  move.z() = 0.0;  // the target stays on the surface plane
  // The scene follows the drag: the target moves the other way.
  target_mm_ -= move;
}

void ViewCamera::set_captured_views(std::vector<ViewPose> poses) {
  captured_ = std::move(poses);
  current_view_ = 0;
  if (captured_.empty()) mode_ = Mode::kFree;
  drag_accum_px_ = Vec2d::Zero();
}

Vec3d ViewCamera::captured_direction(int k) const {
  VDRIG_CHECK(k >= 0 && k < captured_count(), "captured view index out of range");
  return captured_[k].camera_centre().normalized();
}

int ViewCamera::nearest_view(const Vec3d& direction) const {
  int best = -1;
  double best_angle = std::numeric_limits<double>::infinity();
  for (int k = 0; k < captured_count(); ++k) {
    const double a = angle_between(direction, captured_direction(k));
    if (a < best_angle) {
      best_angle = a;
      best = k;
    }
  }
  return best;
}

int ViewCamera::neighbour_view(int from, const Vec2d& camera_motion) const {
  if (from < 0 || from >= captured_count() || camera_motion.norm() == 0.0) return -1;
  const Vec3d dc = captured_direction(from);
  const Mat3d& R = captured_[from].R;
  // The motion in the surface frame, on the tangent plane of the sphere of directions at dc.
  Vec3d m = camera_motion.x() * R.row(0).transpose() + camera_motion.y() * R.row(1).transpose();
  m -= m.dot(dc) * dc;
  if (m.norm() < 1e-12) return -1;  // motion along the line of sight: no direction on the sphere
  m.normalize();
  int best = -1;
  double best_score = std::numeric_limits<double>::infinity();
  const double cos_cone = std::cos(settings_.neighbour_cone_rad);
  for (int k = 0; k < captured_count(); ++k) {
    if (k == from) continue;
    const Vec3d dk = captured_direction(k);
    Vec3d tangent = dk - dk.dot(dc) * dc;  // initial heading of the great circle from dc to dk
    const double angle = angle_between(dc, dk);
    if (tangent.norm() < 1e-9 || angle < 1e-9) continue;  // same or opposite direction: no heading
    const double cos_dev = tangent.normalized().dot(m);
    if (cos_dev <= cos_cone) continue;
    const double score = angle / cos_dev;
    if (score < best_score) {
      best_score = score;
      best = k;
    }
  }
  return best;
}

bool ViewCamera::set_mode(Mode mode) {
  drag_accum_px_ = Vec2d::Zero();
  if (mode == mode_) return true;
  if (mode == Mode::kConstrained) return snap() >= 0;
  // Leaving a captured view: continue orbiting from where it was, around the surface centre.
  const Vec3d c = captured_[current_view_].camera_centre();
  const SphericalDir s = spherical_from_direction(c);
  target_mm_ = Vec3d::Zero();
  set_orbit(s.azimuth_rad, s.zenith_rad, c.norm());
  mode_ = Mode::kFree;
  return true;
}

void ViewCamera::select_view(int k) {
  if (captured_.empty()) return;
  const int n = captured_count();
  current_view_ = ((k % n) + n) % n;
  mode_ = Mode::kConstrained;
  drag_accum_px_ = Vec2d::Zero();
}

int ViewCamera::snap() {
  const int k = nearest_view(free_direction());
  if (k >= 0) select_view(k);
  return k;
}

void ViewCamera::drag(double dx_px, double dy_px) {
  if (mode_ == Mode::kFree) {
    set_orbit(azimuth_rad_ - dx_px * settings_.rad_per_px, zenith_rad_ - dy_px * settings_.rad_per_px, distance_mm_);
    return;
  }
  drag_accum_px_ += Vec2d(dx_px, dy_px);
  if (drag_accum_px_.norm() < settings_.drag_step_px) return;
  const int k = neighbour_view(current_view_, -drag_accum_px_);
  if (k >= 0) current_view_ = k;
  drag_accum_px_ = Vec2d::Zero();
}

void ViewCamera::scroll(double steps) {
  if (mode_ != Mode::kFree) return;
  set_orbit(azimuth_rad_, zenith_rad_, distance_mm_ * std::pow(settings_.zoom_per_step, steps));
}

void ViewCamera::reset() {
  target_mm_ = Vec3d::Zero();
  set_orbit(1.5 * kPi, 0.0, initial_distance_mm_);
  current_view_ = 0;
  mode_ = Mode::kFree;
  drag_accum_px_ = Vec2d::Zero();
}

ViewPose ViewCamera::pose() const {
  if (mode_ == Mode::kConstrained) return captured_[current_view_];
  return orbit_pose(target_mm_, azimuth_rad_, zenith_rad_, distance_mm_);
}

}  // namespace vdrig::viewer

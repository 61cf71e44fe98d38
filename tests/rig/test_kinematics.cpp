// The full rig model (encoder zeros, pan-axis tilt): its documented conventions, checked against constructions of
// their own, and the inverse kinematics' round trip on an imperfect rig.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/rig/kinematics_model.hpp"

namespace vdrig::rig {
namespace {

RigGeometry imperfect() {
  RigGeometry g;
  g.camera_distance_mm = 1800.0;
  g.surface_offset_mm = Vec3d(12.0, -7.0, 3.0);
  g.pan_zero_rad = deg_to_rad(0.3);
  g.tilt_zero_rad = deg_to_rad(-0.7);
  g.pan_axis_tilt_x_rad = deg_to_rad(0.3);
  g.pan_axis_tilt_y_rad = deg_to_rad(-0.4);
  return g;
}

StageSpec wide_stage() {
  StageSpec s;
  s.pan = {deg_to_rad(-360.0), deg_to_rad(360.0), deg_to_rad(30.0), deg_to_rad(60.0), false};
  s.tilt = {deg_to_rad(-5.0), deg_to_rad(90.0), deg_to_rad(30.0), deg_to_rad(60.0), false};
  return s;
}

Mat3d world_from_surface(const RigGeometry& g, const PanTilt& reading) {
  const Mat3d R_cw = Vec3d(1, -1, -1).asDiagonal();
  return R_cw.transpose() * surface_pose(g, reading).R;
}

TEST(Kinematics, ReadingIsTrueAnglePlusZero) {
  // With only the zeros set, reading (zero + a, zero + b) poses the surface as an ideal rig at (a, b).
  RigGeometry g;
  g.pan_zero_rad = deg_to_rad(25.0);
  g.tilt_zero_rad = deg_to_rad(-3.0);
  const PanTilt true_angles{deg_to_rad(40.0), deg_to_rad(30.0)};
  const ViewPose got = surface_pose(g, {true_angles.pan_rad + g.pan_zero_rad, true_angles.tilt_rad + g.tilt_zero_rad});
  const ViewPose ideal = surface_pose(RigGeometry{}, true_angles);
  EXPECT_LT((got.R - ideal.R).norm(), 1e-12);
  EXPECT_LT((got.t - ideal.t).norm(), 1e-9);
  // The ideal rig's documented view direction: zenith = tilt, azimuth = pi/2 - pan.
  const SphericalDir s = spherical_from_direction(view_direction(RigGeometry{}, true_angles));
  EXPECT_NEAR(s.zenith_rad, true_angles.tilt_rad, 1e-12);
  EXPECT_NEAR(s.azimuth_rad, kPi / 2 - true_angles.pan_rad, 1e-12);
}

TEST(Kinematics, PanAxisTiltAsDocumented) {
  // The pan axis seen from the surface is (-cos x sin y, sin x, cos x cos y): panning leaves that surface direction
  // fixed in the world, along Rx(tilt - tilt_zero) e_z, and it is tilted from the surface normal by about
  // hypot(x, y).
  const RigGeometry g = imperfect();
  const double x = g.pan_axis_tilt_x_rad, y = g.pan_axis_tilt_y_rad;
  const Vec3d axis_surface(-std::cos(x) * std::sin(y), std::sin(x), std::cos(x) * std::cos(y));
  for (double tilt_deg : {0.0, 30.0, 70.0}) {
    const double tilt_r = deg_to_rad(tilt_deg);
    const Vec3d expected =
        Eigen::AngleAxisd(tilt_r - g.tilt_zero_rad, Vec3d::UnitX()).toRotationMatrix() * Vec3d::UnitZ();
    for (double pan_deg : {-170.0, 0.0, 45.0, 200.0}) {
      const Mat3d R = world_from_surface(g, {deg_to_rad(pan_deg), tilt_r});
      EXPECT_LT((R * axis_surface - expected).norm(), 1e-12) << pan_deg << ", " << tilt_deg;
    }
  }
  EXPECT_NEAR(rad_to_deg(std::acos(axis_surface.z())), 0.5, 1e-3);
  // The surface origin sits at the offset in the platter frame: panning turns it about the pan axis, at a fixed
  // height along it.
  const Vec3d o = g.surface_offset_mm;
  for (double pan_deg : {0.0, 90.0, 250.0}) {
    const ViewPose pose = surface_pose(g, {deg_to_rad(pan_deg) + g.pan_zero_rad, g.tilt_zero_rad});
    const Mat3d R_cw = Vec3d(1, -1, -1).asDiagonal();
    const Vec3d origin_world = R_cw.transpose() * pose.t + Vec3d(0, 0, g.camera_distance_mm);
    EXPECT_NEAR(origin_world.z(), o.z(), 1e-9);
    EXPECT_NEAR(origin_world.head<2>().norm(), o.head<2>().norm(), 1e-9);
  }
}

TEST(Kinematics, TemplateModelMatchesDoubleModel) {
  const RigGeometry g = imperfect();
  const model::Params p = model::to_params(g);
  const RigGeometry back = model::from_params(p);
  EXPECT_EQ(model::to_params(back), p);
  Mat3d R;
  Vec3d t;
  const PanTilt reading{deg_to_rad(33.0), deg_to_rad(47.0)};
  model::surface_pose(p.data(), reading, &R, &t);
  // The composition written out with Eigen's own rotations, as kinematics.hpp states it.
  const auto rx = [](double a) { return Eigen::AngleAxisd(a, Vec3d::UnitX()).toRotationMatrix(); };
  const Mat3d R_wp = rx(reading.tilt_rad - g.tilt_zero_rad) *
                     Eigen::AngleAxisd(reading.pan_rad - g.pan_zero_rad, Vec3d::UnitZ()).toRotationMatrix();
  const Mat3d A =
      rx(g.pan_axis_tilt_x_rad) * Eigen::AngleAxisd(g.pan_axis_tilt_y_rad, Vec3d::UnitY()).toRotationMatrix();
  const Mat3d R_cw = Vec3d(1, -1, -1).asDiagonal();
  EXPECT_LT((R - R_cw * R_wp * A).norm(), 1e-12);
  EXPECT_LT((t - R_cw * (R_wp * g.surface_offset_mm - Vec3d(0, 0, g.camera_distance_mm))).norm(), 1e-9);
  const ViewPose pose = surface_pose(g, reading);
  EXPECT_LT((pose.R - R).norm(), 1e-15);
  EXPECT_LT((pose.t - t).norm(), 1e-12);
}

TEST(Kinematics, InverseIsExactOnAnImperfectRig) {
  // forward(inverse(d)) == d to rounding, over the hemisphere up to 85 deg (beyond, a negative tilt zero and the
  // offset push some grazing views past the 90 deg tilt limit) and near the pole.
  const RigGeometry g = imperfect();
  std::vector<Vec3d> dirs;
  const int n = 600;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  const double cos_max = std::cos(deg_to_rad(85.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (1.0 - cos_max) * (i + 0.5) / n;
    dirs.push_back(direction_from_spherical(std::fmod(golden * i, 2 * kPi), std::acos(z)));
  }
  for (double zen_deg : {0.0, 1e-6, 0.01, 0.5})
    for (int a = 0; a < 8; ++a) dirs.push_back(direction_from_spherical(a * kPi / 4.0, deg_to_rad(zen_deg)));
  double worst_rad = 0.0;
  for (const Vec3d& d : dirs) {
    const auto pt = inverse_kinematics(g, wide_stage(), d, 0.3);
    ASSERT_TRUE(pt.has_value()) << d.transpose();
    worst_rad = std::max(worst_rad, angle_between(view_direction(g, *pt), d));
  }
  std::printf("imperfect rig: worst round-trip error %.3g rad over %zu directions\n", worst_rad, dirs.size());
  EXPECT_LT(worst_rad, 1e-9);
  // The ideal model's inverse on this rig misses by about the rig's errors: the test can tell them apart.
  RigGeometry ideal;
  ideal.camera_distance_mm = g.camera_distance_mm;
  ideal.surface_offset_mm = g.surface_offset_mm;
  const Vec3d d = direction_from_spherical(deg_to_rad(30.0), deg_to_rad(60.0));
  EXPECT_GT(rad_to_deg(angle_between(view_direction(g, *inverse_kinematics(ideal, wide_stage(), d, 0.3)), d)), 0.3);
}

}  // namespace
}  // namespace vdrig::rig

// The full kinematic fit (calib/kinematic.hpp) on synthetic marker poses: poses of a known imperfect rig with
// marker-like noise, the fit against that truth and its reported standard deviations against the actual errors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "vdrig/calib/kinematic.hpp"
#include "vdrig/rig/kinematics_model.hpp"

namespace vdrig::calib {
namespace {

namespace model = rig::model;

/// The rig: encoder zeros of 0.3 deg, the pan axis tilted by 0.5 deg (0.3, 0.4), off-centre surface.
rig::RigGeometry truth_rig() {
  rig::RigGeometry g;
  g.camera_distance_mm = 2480.0;
  g.surface_offset_mm = Vec3d(12.0, -18.0, 6.0);
  g.pan_zero_rad = deg_to_rad(0.3);
  g.tilt_zero_rad = deg_to_rad(0.3);
  g.pan_axis_tilt_x_rad = deg_to_rad(0.3);
  g.pan_axis_tilt_y_rad = deg_to_rad(0.4);
  return g;
}

/// Marker-pose-like noise (what calib's extrinsics measure on the simulator, docs/calib.md): rotation about the
/// image axes 0.01 deg, about the optical axis 0.004 deg, translation 0.05 mm across and 0.3 mm along the axis.
struct Noise {
  double rot_xy_deg = 0.01, rot_z_deg = 0.004, t_xy_mm = 0.05, t_z_mm = 0.3;
};

std::vector<KinematicObservation> observe(const rig::RigGeometry& g, const std::vector<PanTilt>& readings,
                                          const Noise& noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  std::vector<KinematicObservation> obs;
  for (const PanTilt& pt : readings) {
    ViewPose pose = rig::surface_pose(g, pt);
    const Vec3d w(deg_to_rad(noise.rot_xy_deg) * n01(rng), deg_to_rad(noise.rot_xy_deg) * n01(rng),
                  deg_to_rad(noise.rot_z_deg) * n01(rng));
    if (w.norm() > 0) pose.R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * pose.R;
    pose.t += Vec3d(noise.t_xy_mm * n01(rng), noise.t_xy_mm * n01(rng), noise.t_z_mm * n01(rng));
    obs.push_back({static_cast<int>(obs.size()), pt, pose});
  }
  return obs;
}

/// 24 views: 8 pans at 3 tilts, as a latlong scheme spreads them (tilt up to 60 deg, where markers still pose).
std::vector<PanTilt> scheme_readings() {
  std::vector<PanTilt> r;
  for (double tilt : {15.0, 35.0, 55.0})
    for (int k = 0; k < 8; ++k) r.push_back({deg_to_rad(-157.5 + 45.0 * k + tilt / 5.0), deg_to_rad(tilt)});
  return r;
}

/// Parameter errors in the units a user reads them (mm, deg).
model::Params in_edge_units(const model::Params& p) {
  model::Params q = p;
  for (int i = model::kPanZero; i < model::kParamCount; ++i) q[i] = rad_to_deg(p[i]);
  return q;
}

TEST(KinematicFit, RecoversZerosAndAxisTiltWithPlausibleSigmas) {
  const rig::RigGeometry truth = truth_rig();
  const model::Params want = in_edge_units(model::to_params(truth));
  const char* names[] = {"D",        "offset x",  "offset y",    "offset z",
                         "pan zero", "tilt zero", "axis tilt x", "axis tilt y"};
  double sum_z2 = 0.0, worst_angle_deg = 0.0;
  int count = 0;
  for (unsigned seed = 1; seed <= 40; ++seed) {  // ~1 ms a fit
    const auto obs = observe(truth, scheme_readings(), Noise{}, seed);
    auto fit = fit_rig_geometry(obs);
    ASSERT_TRUE(fit) << fit.error().describe();
    ASSERT_TRUE(fit->sigma.has_value());
    const model::Params got = in_edge_units(model::to_params(fit->geometry));
    const model::Params sigma = in_edge_units(*fit->sigma);
    for (int i = 0; i < model::kParamCount; ++i) {
      const double err = got[i] - want[i];
      if (seed == 1)
        std::printf("%-12s truth %10.4f  fitted %10.4f +- %.4f  (error %+.4f, %.1f sigma)\n", names[i], want[i], got[i],
                    sigma[i], err, err / sigma[i]);
      ASSERT_GT(sigma[i], 0.0) << names[i];
      if (seed <= 6) {
        EXPECT_LT(std::abs(err), 4.0 * sigma[i]) << names[i] << ", seed " << seed;
      }
      sum_z2 += (err / sigma[i]) * (err / sigma[i]);
      ++count;
      if (i >= model::kPanZero) {
        EXPECT_LT(std::abs(err), 0.02) << names[i] << ", seed " << seed;  // the target
        worst_angle_deg = std::max(worst_angle_deg, std::abs(err));
      }
    }
    EXPECT_LT(std::abs(got[model::kDistance] - want[model::kDistance]), 0.5);
    // The noise the fit estimated is the noise put in (within the scatter of 24 views).
    EXPECT_NEAR(fit->noise_rotation_xy_deg, Noise{}.rot_xy_deg, 0.4 * Noise{}.rot_xy_deg);
    EXPECT_NEAR(fit->noise_translation_z_mm, Noise{}.t_z_mm, 0.4 * Noise{}.t_z_mm);
  }
  // Errors over sigma have unit spread if the sigmas are right: neither inflated nor too optimistic (over 300
  // seeds each parameter's came out 0.99-1.06).
  const double rms_z = std::sqrt(sum_z2 / count);
  std::printf("worst angle error %.4f deg; rms of error / sigma over %d estimates: %.2f\n", worst_angle_deg, count,
              rms_z);
  EXPECT_GT(rms_z, 0.8);
  EXPECT_LT(rms_z, 1.25);
}

TEST(KinematicFit, AnOutlierViewWeighsLittle) {
  // One view posed 0.15 deg and 1.5 mm off, as a near-grazing view whose markers were barely found can be.
  const rig::RigGeometry truth = truth_rig();
  auto obs = observe(truth, scheme_readings(), Noise{}, 7);
  obs[5].pose.R = Eigen::AngleAxisd(deg_to_rad(0.15), Vec3d::UnitX()).toRotationMatrix() * obs[5].pose.R;
  obs[5].pose.t += Vec3d(1.5, 0.0, 0.0);
  auto fit = fit_rig_geometry(obs);
  ASSERT_TRUE(fit) << fit.error().describe();
  EXPECT_EQ(fit->downweighted_views, std::vector<int>{5});
  ASSERT_TRUE(fit->sigma.has_value());
  const model::Params got = model::to_params(fit->geometry), want = model::to_params(truth);
  for (int i = model::kPanZero; i < model::kParamCount; ++i) {
    EXPECT_LT(rad_to_deg(std::abs(got[i] - want[i])), 0.01) << i;
    EXPECT_LT(std::abs(got[i] - want[i]), 4.0 * (*fit->sigma)[i]) << i;
  }
  EXPECT_NEAR(fit->noise_rotation_xy_deg, Noise{}.rot_xy_deg, 0.4 * Noise{}.rot_xy_deg);
}

TEST(KinematicFit, ExactOnNoiseFreePosesFromAFarStart) {
  // A surface mounted turned by 40 deg on the platter is a pan zero of 40 deg: the start must find it.
  rig::RigGeometry truth = truth_rig();
  truth.pan_zero_rad = deg_to_rad(40.0);
  truth.tilt_zero_rad = deg_to_rad(-1.5);
  truth.pan_axis_tilt_x_rad = deg_to_rad(-2.0);
  Noise none{0, 0, 0, 0};
  auto fit = fit_rig_geometry(observe(truth, scheme_readings(), none, 1));
  ASSERT_TRUE(fit) << fit.error().describe();
  const model::Params got = model::to_params(fit->geometry), want = model::to_params(truth);
  for (int i = 0; i < model::kParamCount; ++i) EXPECT_NEAR(got[i], want[i], 1e-7) << i;
  EXPECT_LT(fit->rms_translation_mm, 1e-6);
  EXPECT_LT(fit->max_rotation_deg, 1e-6);
}

TEST(KinematicFit, UndeterminedParametersAreAClearError) {
  const rig::RigGeometry truth = truth_rig();
  // All views at one pan: the tilt zero and the axis tilt about x cannot be told apart.
  std::vector<PanTilt> one_pan;
  for (double tilt : {10.0, 25.0, 40.0, 55.0, 70.0}) one_pan.push_back({deg_to_rad(30.0), deg_to_rad(tilt)});
  auto fit = fit_rig_geometry(observe(truth, one_pan, Noise{}, 3));
  ASSERT_FALSE(fit);
  EXPECT_EQ(fit.error().code, ErrorCode::kInvalidArgument);
  std::printf("one pan: %s\n", fit.error().message.c_str());
  EXPECT_NE(fit.error().message.find("do not determine"), std::string::npos) << fit.error().message;
  EXPECT_NE(fit.error().message.find("tilt zero"), std::string::npos) << fit.error().message;
  // Too few views, or all at one position.
  const auto obs = observe(truth, scheme_readings(), Noise{}, 3);
  EXPECT_FALSE(fit_rig_geometry(std::span(obs).first(1)));
  std::vector<KinematicObservation> same(4, obs.front());
  EXPECT_FALSE(fit_rig_geometry(same));
}

TEST(KinematicFit, JsonRoundTripAndOldFiles) {
  KinematicFit fit;
  fit.geometry = truth_rig();
  const auto back = KinematicFit::geometry_from_json(fit.to_json());
  ASSERT_TRUE(back) << back.error().describe();
  const model::Params a = model::to_params(fit.geometry), b = model::to_params(back.value());
  for (int i = 0; i < model::kParamCount; ++i) EXPECT_NEAR(a[i], b[i], 1e-12) << i;
  EXPECT_TRUE(fit.to_json()["sigma"].is_null());

  // A views.json written before the full model: distance and offset only, which is an ideal rig otherwise.
  const nlohmann::json old = {{"camera_distance_mm", 2490.5}, {"surface_offset_mm", {1.0, 2.0, 3.0}}};
  const auto g = KinematicFit::geometry_from_json(old);
  ASSERT_TRUE(g) << g.error().describe();
  EXPECT_EQ(g->camera_distance_mm, 2490.5);
  EXPECT_EQ(g->surface_offset_mm, Vec3d(1.0, 2.0, 3.0));
  EXPECT_EQ(g->pan_zero_rad, 0.0);
  EXPECT_EQ(g->tilt_zero_rad, 0.0);
  EXPECT_EQ(g->pan_axis_tilt_x_rad, 0.0);
  EXPECT_EQ(g->pan_axis_tilt_y_rad, 0.0);

  nlohmann::json bad = old;
  bad["pan_zero_deg"] = "0.3";
  EXPECT_EQ(KinematicFit::geometry_from_json(bad).error().code, ErrorCode::kCorrupt);
  bad = old;
  bad["camera_distance_mm"] = -1.0;
  EXPECT_EQ(KinematicFit::geometry_from_json(bad).error().code, ErrorCode::kCorrupt);
  bad = old;
  bad.erase("surface_offset_mm");
  EXPECT_EQ(KinematicFit::geometry_from_json(bad).error().code, ErrorCode::kCorrupt);
}

}  // namespace
}  // namespace vdrig::calib

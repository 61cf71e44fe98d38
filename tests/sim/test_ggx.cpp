// The GGX material against independent numerical integrals: the distribution is normalised (integral of D(h) hz over
// the hemisphere is 1, isotropic and anisotropic), D and Smith's Lambda are consistent (the weak white furnace
// test of Heitz 2014: the integral of D(h) G1(v) / (4 vz) over all light directions is 1), the BRDF is reciprocal,
// and the scene's radiance keeps the Lambertian convention: a lossless white GGX surface reflects at most the
// irradiance (directional albedo <= 1, close to 1 when smooth, equal to an integral over half vectors under normal
// light) and a white Lambertian kd = 1 reflects exactly it.
#include <gtest/gtest.h>

#include <cmath>

#include "vdrig/sim/ggx.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {
namespace {

// Midpoint rule over the directions theta in [0, theta_max], phi in [0, 2 pi): sum f(w) sin(theta) dtheta dphi.
template <typename F>
double integrate_sphere_cap(F&& f, double theta_max, int n_theta, int n_phi) {
  const double dt = theta_max / n_theta, dp = 2.0 * kPi / n_phi;
  double sum = 0.0;
  for (int i = 0; i < n_theta; ++i) {
    const double t = (i + 0.5) * dt, st = std::sin(t), ct = std::cos(t);
    for (int j = 0; j < n_phi; ++j) {
      const double p = (j + 0.5) * dp;
      sum += f(Vec3d(st * std::cos(p), st * std::sin(p), ct)) * st;
    }
  }
  return sum * dt * dp;
}

TEST(Ggx, DistributionIsNormalised) {
  for (const auto& [ax, ay] : {std::pair{0.1, 0.1}, {0.3, 0.3}, {0.7, 0.7}, {0.1, 0.4}, {0.5, 0.15}}) {
    const double integral =
        integrate_sphere_cap([&](const Vec3d& h) { return ggx_distribution(h, ax, ay) * h.z(); }, kPi / 2, 6000, 512);
    EXPECT_NEAR(integral, 1.0, 2e-3) << ax << " " << ay;
  }
}

TEST(Ggx, WeakWhiteFurnace) {
  for (const auto& [ax, ay] : {std::pair{0.3, 0.3}, {0.6, 0.6}, {0.2, 0.5}})
    for (const double theta_v_deg : {0.0, 30.0, 60.0, 80.0}) {
      const double tv = deg_to_rad(theta_v_deg);
      const Vec3d v(std::sin(tv) * std::cos(0.4), std::sin(tv) * std::sin(0.4), std::cos(tv));
      const double g1 = 1.0 / (1.0 + ggx_lambda(v, ax, ay));
      const double integral = integrate_sphere_cap(
          [&](const Vec3d& l) { return ggx_distribution((l + v).normalized(), ax, ay) * g1 / (4.0 * v.z()); }, kPi,
          3000, 512);
      EXPECT_NEAR(integral, 1.0, 3e-3) << ax << " " << ay << " at " << theta_v_deg << " deg";
    }
}

TEST(Ggx, BrdfIsReciprocalAndZeroBelowTheHorizon) {
  const Vec3d f0(0.9, 0.5, 0.04);
  const Vec3d l = Vec3d(0.3, -0.2, 0.9).normalized(), v = Vec3d(-0.5, 0.4, 0.6).normalized();
  const Vec3d a = ggx_brdf(l, v, 0.2, 0.45, f0), b = ggx_brdf(v, l, 0.2, 0.45, f0);
  EXPECT_LT((a - b).norm(), 1e-12 * a.norm());
  EXPECT_GT(a.minCoeff(), 0.0);
  EXPECT_EQ(ggx_brdf(Vec3d(0.3, 0, -0.1).normalized(), v, 0.2, 0.2, f0), Vec3d::Zero());
}

// A scene whose only material is `m`, lit by one point light from polar angle theta_l with irradiance 1 at the
// origin.
Scene single_material_scene(const Material& m, double theta_l) {
  Scene s;
  s.materials = {m};
  const Vec3d dir(std::sin(theta_l), 0.0, std::cos(theta_l));
  const double d = 5000.0;
  s.lights = {{dir * d, Vec3d::Constant(d * d / std::cos(theta_l))}};
  return s;
}

// (1 / (pi E)) times the integral of L(v) cos(theta_v) over the hemisphere: the directional albedo with E = 1.
Vec3d albedo(const Scene& s) {
  Vec3d sum = Vec3d::Zero();
  for (int c = 0; c < 3; ++c)
    sum[c] = integrate_sphere_cap([&](const Vec3d& v) { return s.radiance(Vec3d::Zero(), v)[c] * v.z(); }, kPi / 2,
                                  c == 0 ? 3000 : 200, c == 0 ? 512 : 64);
  return sum / kPi;
}

TEST(Ggx, SceneRadianceIsPiTimesTheBrdfTimesTheIrradiance) {
  Material m{"ggx", {0.1, 0.2, 0.3}};
  m.kind = MaterialKind::kGgx;
  m.roughness = 0.2;
  m.roughness_y = 0.35;
  m.f0 = {0.95, 0.64, 0.54};
  const Scene s = single_material_scene(m, deg_to_rad(40));
  const Vec3d l = s.lights[0].position_mm.normalized();
  for (const Vec3d& v : {Vec3d(-0.6, 0.1, 0.79), Vec3d(0.2, 0.5, 0.84), Vec3d(-0.64, 0.0, 0.77)}) {
    const Vec3d vn = v.normalized();
    // Flat surface: the local frame is the surface frame (tangent +x).
    const Vec3d expected = m.kd + kPi * ggx_brdf(l, vn, 0.2, 0.35, m.f0);
    EXPECT_LT((s.radiance(Vec3d::Zero(), vn) - expected).norm(), 1e-9 * expected.norm()) << vn.transpose();
  }
  EXPECT_FALSE(s.phong_truth(Vec3d::Zero()).has_value());  // the truth is not of Phong form
}

TEST(Ggx, WhiteFurnaceEnergy) {
  Material white{"white", Vec3d::Ones()};  // Lambertian kd = 1 reflects exactly the irradiance
  EXPECT_NEAR(albedo(single_material_scene(white, deg_to_rad(30)))[0], 1.0, 1e-3);

  Material mirror{"lossless ggx"};  // f0 = 1: every loss is Smith's single-scattering shadowing
  mirror.kind = MaterialKind::kGgx;
  mirror.f0 = Vec3d::Ones();
  for (const double roughness : {0.1, 0.3, 0.6})
    for (const double theta_deg : {0.0, 45.0, 75.0}) {
      mirror.roughness = roughness;
      const double a = albedo(single_material_scene(mirror, deg_to_rad(theta_deg)))[0];
      EXPECT_LE(a, 1.0 + 2e-3) << roughness << " at " << theta_deg;
      // Smooth surfaces lose almost nothing; rough ones at grazing light lose most (single scattering only).
      if (roughness == 0.1 && theta_deg < 60) {
        EXPECT_GT(a, 0.97) << theta_deg;
      }
      if (theta_deg == 0.0) {
        // Independently, in half-vector space: under normal light v = 2 hz h - l and dv = 4 hz dh, so the albedo is
        // the integral of D(h) hz G1(v) over theta_h < 45 deg (beyond, v is below the horizon: a closed-form loss of
        // alpha^2 / (1 + alpha^2) of the energy).
        const Vec3d l = Vec3d::UnitZ();
        const double in_half_space = integrate_sphere_cap(
            [&](const Vec3d& h) {
              const Vec3d v = 2.0 * h.z() * h - l;
              return ggx_distribution(h, roughness, roughness) * h.z() / (1.0 + ggx_lambda(v, roughness, roughness));
            },
            kPi / 4, 3000, 64);
        EXPECT_NEAR(a, in_half_space, 2e-3) << roughness;
        EXPECT_LT(a, 1.0 / (1.0 + roughness * roughness)) << roughness;
      }
    }
}

}  // namespace
}  // namespace vdrig::sim

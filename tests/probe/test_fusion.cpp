// Fusing probes on proxy geometry (probe/fusion.hpp) on a synthetic room whose ground truth is known: the walls of
// a 4 x 3 x 2.6 m box emit a radiance that is a function of the wall point (stripes and gradients per wall, a bright
// window on one wall). Probes are rendered analytically (each pixel the pixel-averaged radiance of the walls its
// rays hit), fused at a new position and compared with the probe rendered there.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "probe_support.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {
namespace {

const ProxyBox kRoom{Vec3d(-2000, -1500, 0), Vec3d(2000, 1500, 2600)};
const Vec3d kWindowCentre(2000, 0, 1400);  // on the wall x = +2000: y in [-400, 400], z in [1000, 1800]
const Rgb kWindowRadiance(30, 28, 24);

// Radiance leaving wall point x (on the box) whose inward normal is n.
Rgb wall_radiance(const Vec3d& x, const Vec3d& n) {
  if (n.x() < -0.5 && std::abs(x.y()) <= 400 && std::abs(x.z() - 1400) <= 400) return kWindowRadiance;
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (std::abs(n[k]) > std::abs(n[axis])) axis = k;
  const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // in-plane coordinates
  static const Rgb base[6] = {{0.6, 0.4, 0.3}, {0.3, 0.5, 0.6},   {0.5, 0.6, 0.3},
                              {0.6, 0.3, 0.5}, {0.35, 0.3, 0.25}, {0.9, 0.9, 0.85}};
  const Rgb& c = base[2 * axis + (n[axis] > 0 ? 1 : 0)];
  const double m = (1.0 + 0.4 * std::sin(2 * kPi * x[a] / 900.0)) * (1.2 + 0.3 * std::cos(2 * kPi * x[b] / 1300.0));
  return c * m;
}

// Ground-truth probe at `position` (probe frame rotated by `rotation`): every pixel the solid-angle-weighted mean of
// ss x ss rays through it (what a camera pixel integrates).
Probe render_room(const Vec3d& position, int height, const Mat3d& rotation = Mat3d::Identity(), int ss = 3) {
  Probe p = make_probe(height);
  p.position_mm = position;
  p.rotation = rotation;
  const int W = p.width(), H = p.height();
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      Rgb sum = Rgb::Zero();
      double wsum = 0;
      for (int b = 0; b < ss; ++b)
        for (int a = 0; a < ss; ++a) {
          const double u = i + (a + 0.5) / ss - 0.5, v = j + (b + 0.5) / ss - 0.5;
          const double w = std::sin(kPi * (v + 0.5) / H);
          const ProxyHit h = intersect_from_inside(kRoom, position, rotation * latlong_direction(u, v, W, H));
          EXPECT_TRUE(h.hit);
          sum += w * wall_radiance(h.point_mm, h.normal);
          wsum += w;
        }
      p.set_pixel(i, j, sum / wsum);
    }
  return p;
}

// Solid-angle-weighted mean of |Y - Y_ref| / Y_ref over the map (luminance), or over the pixels (i, j) for which
// `only(i, j)` holds.
double mean_relative_error(const Probe& p, const Probe& ref, const std::function<bool(int, int)>& only = {}) {
  EXPECT_EQ(p.width(), ref.width());
  const int W = ref.width(), H = ref.height();
  double err = 0, sr = 0;
  for (int j = 0; j < H; ++j) {
    const double sa = latlong_pixel_solid_angle(j, W, H);
    for (int i = 0; i < W; ++i) {
      if (only && !only(i, j)) continue;
      const double y = luminance(p.pixel(i, j)), y_ref = luminance(ref.pixel(i, j));
      err += sa * std::abs(y - y_ref) / y_ref;
      sr += sa;
    }
  }
  return err / sr;
}

// Energy centroid direction (world frame) of the window's pixels (luminance above 5).
Vec3d window_direction(const Probe& p) {
  Vec3d sum = Vec3d::Zero();
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      const double y = luminance(p.pixel(i, j));
      if (y > 5)
        sum += y * latlong_pixel_solid_angle(j, p.width(), p.height()) * latlong_direction(i, j, p.width(), p.height());
    }
  return (p.rotation * sum).normalized();
}

// The wrong fusion: the probes' maps averaged direction by direction, as if the scene were infinitely far.
Probe naive_average(const std::vector<Probe>& probes) {
  Probe out = make_probe(probes[0].height());
  for (const Probe& p : probes) out.radiance += p.radiance / static_cast<double>(probes.size());
  return out;
}

const std::vector<Vec3d> kProbePositions = {
    {-1200, -800, 1200}, {1000, -700, 1500}, {-900, 900, 900}, {1100, 800, 1300}};
const Vec3d kTarget(200, 100, 1100);
constexpr int kHeight = 64;  // 128 x 64 maps: 2.8 degrees per pixel

std::vector<Probe> room_probes(int height = kHeight) {
  std::vector<Probe> probes;
  for (const Vec3d& p : kProbePositions) probes.push_back(render_room(p, height));
  return probes;
}

TEST(ProxyGeometry, BoxIntersectionFromInside) {
  const Vec3d o(0, 0, 1000);
  ProxyHit h = intersect_from_inside(kRoom, o, Vec3d(1, 0, 0));
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.distance_mm, 2000, 1e-9);
  EXPECT_TRUE(h.normal.isApprox(Vec3d(-1, 0, 0)));
  h = intersect_from_inside(kRoom, o, Vec3d(0, 0, -5));  // any length
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.distance_mm, 1000, 1e-9);
  EXPECT_TRUE(h.normal.isApprox(Vec3d(0, 0, 1)));
  // A diagonal ray meets the nearer wall: y = -1500 at t = 1500 sqrt(2) before x = 2000.
  h = intersect_from_inside(kRoom, o, Vec3d(1, -1, 0));
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.distance_mm, 1500 * std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(h.point_mm.y(), -1500, 1e-9);
  EXPECT_TRUE(h.normal.isApprox(Vec3d(0, 1, 0)));
  EXPECT_FALSE(intersect_from_inside(kRoom, Vec3d(3000, 0, 1000), Vec3d(-1, 0, 0)).hit);  // outside
  EXPECT_FALSE(intersect_from_inside(kRoom, o, Vec3d::Zero()).hit);
}

TEST(ProxyGeometry, SphereIntersectionFromInside) {
  const ProxySphere s{Vec3d(100, 200, 300), 1000};
  for (const Vec3d& d : fibonacci_directions(50)) {
    const ProxyHit h = intersect_from_inside(s, s.centre_mm, d);
    ASSERT_TRUE(h.hit);
    EXPECT_NEAR(h.distance_mm, 1000, 1e-9);
  }
  const ProxyHit h = intersect_from_inside(s, s.centre_mm + Vec3d(600, 0, 0), Vec3d(1, 0, 0));
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.distance_mm, 400, 1e-9);
  EXPECT_TRUE(h.normal.isApprox(Vec3d(-1, 0, 0)));
  EXPECT_FALSE(intersect_from_inside(s, s.centre_mm + Vec3d(1200, 0, 0), Vec3d(-1, 0, 0)).hit);
}

TEST(ProxyGeometry, ProxyDepthPutsEveryPixelOnAWall) {
  Probe p = make_probe(16);
  p.position_mm = Vec3d(-300, 400, 800);
  p.rotation = Eigen::AngleAxisd(0.7, Vec3d(1, 2, 3).normalized()).toRotationMatrix();
  const cv::Mat depth = proxy_depth(p, kRoom);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      const double z = depth.at<float>(j, i);
      ASSERT_GT(z, 0);
      const Vec3d x = p.position_mm + z * (p.rotation * latlong_direction(i, j, p.width(), p.height()));
      // On the box: inside (to float precision) and on one of its six planes.
      double to_wall = 1e30;
      for (int k = 0; k < 3; ++k) {
        EXPECT_GT(x[k], kRoom.min_mm[k] - 0.01);
        EXPECT_LT(x[k], kRoom.max_mm[k] + 0.01);
        to_wall = std::min({to_wall, std::abs(x[k] - kRoom.min_mm[k]), std::abs(x[k] - kRoom.max_mm[k])});
      }
      EXPECT_LT(to_wall, 0.01) << "pixel " << i << ", " << j;
    }
}

TEST(Reproject, ToItsOwnPositionIsTheIdentity) {
  const Probe p = render_room(kProbePositions[0], kHeight);
  cv::Mat w;
  const Probe r = reproject(p, p.position_mm, kRoom, kHeight, &w);
  const double err = mean_relative_error(r, p);
  std::printf("reprojection to its own position: mean relative error %.3g\n", err);
  EXPECT_LT(err, 1e-5);
  double wmin = 1e30;
  cv::minMaxLoc(w, &wmin);
  EXPECT_GT(wmin, 0.99);  // the probe sees every point of its own map head-on in agreement, at full density
  // A rotated source (its frame turned, same room): reprojection to its position in a world-aligned map recovers
  // the world-aligned ground truth up to one bilinear resampling.
  const Mat3d rot = Eigen::AngleAxisd(0.9, Vec3d(0.3, -1, 0.5).normalized()).toRotationMatrix();
  const Probe rotated = render_room(kProbePositions[0], kHeight, rot);
  const double err_rot = mean_relative_error(reproject(rotated, p.position_mm, kRoom, kHeight), p);
  const double err_ignored = mean_relative_error(rotated, p);  // the rotation ignored
  std::printf("rotated source: %.4f after reprojection, %.4f with its rotation ignored\n", err_rot, err_ignored);
  EXPECT_LT(err_rot, 0.06);
  EXPECT_GT(err_ignored, 5 * err_rot);
}

TEST(Reproject, WindowDirectionFollowsThePosition) {
  const Probe truth = render_room(kTarget, kHeight);
  const Vec3d true_dir = window_direction(truth);
  // The renderer's window centroid lies near the direction to the window's centre (perspective shifts it a little).
  EXPECT_LT(rad_to_deg(angle_between(true_dir, (kWindowCentre - kTarget).normalized())), 2.0);
  for (const Vec3d& pos : kProbePositions) {
    const Probe source = render_room(pos, kHeight);
    const Probe moved = reproject(source, kTarget, kRoom, kHeight);
    const double moved_deg = rad_to_deg(angle_between(window_direction(moved), true_dir));
    const double raw_deg = rad_to_deg(angle_between(window_direction(source), true_dir));
    std::printf("window seen from (%g, %g, %g): %.2f deg off after reprojection, %.2f deg without\n", pos.x(), pos.y(),
                pos.z(), moved_deg, raw_deg);
    EXPECT_LT(moved_deg, 1.5);  // half a pixel
    EXPECT_GT(raw_deg, 10.0);   // the parallax the reprojection undid
  }
}

TEST(Fuse, MatchesGroundTruthAndBeatsNaiveAveraging) {
  const std::vector<Probe> probes = room_probes();
  const Probe truth = render_room(kTarget, kHeight);
  FusionStats stats;
  auto fused = fuse(probes, kTarget, kRoom, {}, &stats);
  ASSERT_TRUE(fused) << fused.error().describe();
  EXPECT_EQ(fused->width(), truth.width());
  EXPECT_TRUE(fused->position_mm.isApprox(kTarget));
  EXPECT_EQ(stats.uncovered_pixels, 0);
  ASSERT_EQ(stats.weight_share.size(), probes.size());
  const double err = mean_relative_error(*fused, truth);
  const double err_naive = mean_relative_error(naive_average(probes), truth);
  // Uniform weights (reprojection kept, weighting off) and the single nearest probe reprojected.
  FusionOptions uniform;
  uniform.angular_exponent = 0;
  uniform.resolution_exponent = 0;
  const double err_uniform = mean_relative_error(*fuse(probes, kTarget, kRoom, uniform), truth);
  FusionOptions angular_only;  // the thesis' eq. 5.5 weighting alone
  angular_only.resolution_exponent = 0;
  const double err_angular = mean_relative_error(*fuse(probes, kTarget, kRoom, angular_only), truth);
  double err_single = 1e30;
  for (const Probe& p : probes)
    err_single = std::min(err_single, mean_relative_error(reproject(p, kTarget, kRoom, kHeight), truth));
  std::printf(
      "fused %.4f, uniform weights %.4f, angular weight only %.4f, best single reprojected %.4f, naive "
      "average %.4f; shares",
      err, err_uniform, err_angular, err_single, err_naive);
  for (double s : stats.weight_share) std::printf(" %.3f", s);
  std::printf("\n");
  EXPECT_LT(err, 0.035);
  EXPECT_GT(err_naive, 5 * err);
  EXPECT_LT(err, 0.8 * err_uniform);  // the density weight matters on view-independent walls
  EXPECT_LT(err, 0.8 * err_angular);
  EXPECT_LT(err, 0.8 * err_single);  // fusing beats the best single probe
}

TEST(Fuse, ShadingAtTheNewPositionMatchesGroundTruth) {
  const std::vector<Probe> probes = room_probes();
  const Probe truth = render_room(kTarget, kHeight);
  auto fused = fuse(probes, kTarget, kRoom);
  ASSERT_TRUE(fused) << fused.error().describe();
  const std::vector<Vec3d> normals = fibonacci_directions(128);
  const IrradianceIntegrator brute_truth(truth), brute_fused(*fused);
  const Probe naive = naive_average(probes);
  const IrradianceIntegrator brute_naive(naive);
  const auto lights = median_cut(*fused, 64);
  double e_brute = 0, e_lights = 0, e_naive = 0, max_brute = 0, max_lights = 0;
  for (const Vec3d& n : normals) {
    const double ref = luminance(brute_truth.irradiance(n));
    const double b = std::abs(luminance(brute_fused.irradiance(n)) - ref) / ref;
    const double l = std::abs(luminance(irradiance_from_lights(lights, n)) - ref) / ref;
    e_brute += b / normals.size();
    e_lights += l / normals.size();
    e_naive += std::abs(luminance(brute_naive.irradiance(n)) - ref) / ref / normals.size();
    max_brute = std::max(max_brute, b);
    max_lights = std::max(max_lights, l);
  }
  std::printf(
      "irradiance at %zu normals vs ground truth: fused brute force mean %.4f max %.4f; fused 64 median-cut "
      "lights mean %.4f max %.4f; naive average mean %.4f\n",
      normals.size(), e_brute, max_brute, e_lights, max_lights, e_naive);
  EXPECT_LT(e_brute, 0.01);
  EXPECT_LT(max_brute, 0.03);
  EXPECT_LT(e_lights, 0.03);
  EXPECT_LT(max_lights, 0.08);
  EXPECT_GT(e_naive, 3 * e_brute);
}

// A dark object in front of probe 0 hides part of the walls from it; its depth map says so. With the visibility
// test (thesis eq. 5.4) the hidden points come from the other probes; without it (depth dropped, the proxy assumed
// unobstructed) the object's darkness leaks into the fused map.
TEST(Fuse, DepthVisibilityKeepsOccludersOut) {
  std::vector<Probe> probes = room_probes();
  Probe& p0 = probes[0];
  p0.depth_mm = proxy_depth(p0, kRoom);
  const Vec3d toward(-1, 0, 0);  // the wall nearest to probe 0, which it sees best of all probes
  int hidden = 0;
  for (int j = 0; j < p0.height(); ++j)
    for (int i = 0; i < p0.width(); ++i)
      if (angle_between(latlong_direction(i, j, p0.width(), p0.height()), toward) < deg_to_rad(55)) {
        p0.radiance.at<cv::Vec3f>(j, i) = cv::Vec3f(0.02f, 0.02f, 0.02f);
        p0.depth_mm.at<float>(j, i) = 300.0f;
        ++hidden;
      }
  ASSERT_GT(hidden, 50);
  const Probe truth = render_room(kTarget, kHeight);
  FusionStats stats;
  auto with_depth = fuse(probes, kTarget, kRoom, {}, &stats);
  ASSERT_TRUE(with_depth);
  EXPECT_EQ(stats.uncovered_pixels, 0);
  std::vector<Probe> no_depth = probes;
  no_depth[0].depth_mm = cv::Mat();
  auto without = fuse(no_depth, kTarget, kRoom);
  ASSERT_TRUE(without);
  // Over the whole map and over the target pixels that look at the wall points hidden from probe 0.
  auto hidden_from_p0 = [&](int i, int j) {
    const ProxyHit h = intersect_from_inside(kRoom, kTarget, latlong_direction(i, j, truth.width(), truth.height()));
    return angle_between((h.point_mm - p0.position_mm).normalized(), toward) < deg_to_rad(55);
  };
  const double err = mean_relative_error(*with_depth, truth), err_blind = mean_relative_error(*without, truth);
  const double err_hidden = mean_relative_error(*with_depth, truth, hidden_from_p0),
               err_hidden_blind = mean_relative_error(*without, truth, hidden_from_p0);
  std::printf(
      "occluder in front of probe 0: fused error %.4f with its depth, %.4f without; on the hidden points "
      "%.4f and %.4f\n",
      err, err_blind, err_hidden, err_hidden_blind);
  EXPECT_LT(err, 0.035);
  EXPECT_GT(err_blind, 1.3 * err);
  EXPECT_LT(err_hidden, 0.09);  // the other probes see that wall from farther away
  EXPECT_GT(err_hidden_blind, 5 * err_hidden);

  // Alone, the occluded probe cannot see those points: they are counted and filled from it without reprojection.
  auto alone = fuse({p0}, kTarget, kRoom, {}, &stats);
  ASSERT_TRUE(alone);
  EXPECT_GT(stats.uncovered_pixels, 20);
  EXPECT_GT(stats.uncovered_sr, 0.01);
  std::printf("occluded probe alone: %d pixels (%.3f sr) uncovered\n", stats.uncovered_pixels, stats.uncovered_sr);
}

// fuse_cube (the GPU fusion's CPU reference) goes through the same weights as fuse(): fused_radiance along a lat-long
// pixel's centre direction is that pixel of fuse()'s map (both float-rounded), occluder and fallback included.
TEST(FuseCube, FusedRadianceIsFusesPixelAndTheCubeHoldsItAtTexelCentres) {
  std::vector<Probe> probes = room_probes();
  for (Probe& p : probes) p.depth_mm = proxy_depth(p, kRoom);
  for (int j = 0; j < probes[0].height(); ++j)  // a dark object in front of probe 0, as above
    for (int i = 0; i < probes[0].width(); ++i)
      if (angle_between(latlong_direction(i, j, probes[0].width(), probes[0].height()), Vec3d(-1, 0, 0)) <
          deg_to_rad(40)) {
        probes[0].radiance.at<cv::Vec3f>(j, i) = cv::Vec3f(0.02f, 0.02f, 0.02f);
        probes[0].depth_mm.at<float>(j, i) = 300.0f;
      }
  auto map = fuse(probes, kTarget, kRoom);
  ASSERT_TRUE(map);
  double worst = 0;
  for (int j = 0; j < map->height(); ++j)
    for (int i = 0; i < map->width(); ++i) {
      const Rgb c = fused_radiance(probes, kTarget, kRoom, latlong_direction(i, j, map->width(), map->height()));
      worst = std::max(worst, (c - map->pixel(i, j)).cwiseAbs().maxCoeff() / std::max(1e-3, c.maxCoeff()));
    }
  EXPECT_LT(worst, 1e-6);  // float storage of the map
  int uncovered = -1;
  auto cube = fuse_cube(probes, kTarget, kRoom, 8, {}, &uncovered);
  ASSERT_TRUE(cube);
  EXPECT_EQ(uncovered, 0);
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int t = 0; t < 8; ++t) {
      const Vec3d d = cube_direction(static_cast<CubeFace>(f), t + 0.5, 7 - t + 0.5, 8);
      const Rgb want = fused_radiance(probes, kTarget, kRoom, d), got = cube->texel(static_cast<CubeFace>(f), t, 7 - t);
      EXPECT_LT((want - got).norm(), 1e-5 * std::max(1.0, want.norm())) << f << " " << t;
    }
  // Alone and blinded by its occluder, probe 0 leaves texels to the fallback, counted.
  auto alone = fuse_cube({probes[0]}, kTarget, kRoom, 16, {}, &uncovered);
  ASSERT_TRUE(alone);
  EXPECT_GT(uncovered, 0);
  auto outside = fuse_cube(probes, Vec3d(2500, 0, 1000), kRoom, 8);
  ASSERT_FALSE(outside);
  EXPECT_NE(outside.error().message.find("not inside the room"), std::string::npos);
  EXPECT_FALSE(fuse_cube(probes, kTarget, kRoom, 0));
}

TEST(Fuse, RejectsBadInput) {
  const std::vector<Probe> probes = room_probes(8);
  EXPECT_TRUE(fuse(probes, kTarget, kRoom));
  auto expect_invalid = [](const Result<Probe>& r, const char* what) {
    ASSERT_FALSE(r) << what;
    EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument) << what;
    std::printf("%s -> %s\n", what, r.error().message.c_str());
  };
  expect_invalid(fuse({}, kTarget, kRoom), "no probes");
  std::vector<Probe> mixed = probes;
  mixed.push_back(render_room(kTarget, 4));
  expect_invalid(fuse(mixed, kTarget, kRoom), "different sizes");
  expect_invalid(fuse(probes, Vec3d(2500, 0, 1000), kRoom), "position outside");
  std::vector<Probe> outside = probes;
  outside[1].position_mm = Vec3d(0, 0, -10);
  expect_invalid(fuse(outside, kTarget, kRoom), "probe outside");
  expect_invalid(fuse(probes, kTarget, ProxyBox{Vec3d(0, 0, 0), Vec3d(100, -1, 100)}), "inverted box");
  FusionOptions bad;
  bad.min_cosine = 1.5;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("min cosine"), std::string::npos);
  expect_invalid(fuse(probes, kTarget, kRoom, bad), "bad options");
  bad = {};
  bad.resolution_exponent = -1;
  EXPECT_FALSE(bad.is_valid());
  bad = {};
  bad.min_distance_mm = 0;
  EXPECT_FALSE(bad.is_valid());
  EXPECT_TRUE(FusionOptions{}.is_valid());
}

TEST(FusionOptions, HeightIsLimited) {
  // Issue #18: `probe fuse --height 100000` asked for a 200000 x 100000 map (bad_alloc).
  FusionOptions o;
  o.height = FusionOptions::kMaxHeight;
  EXPECT_TRUE(o.is_valid());
  o.height = 100000;
  std::string why;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find(std::to_string(FusionOptions::kMaxHeight)), std::string::npos) << why;
}

}  // namespace
}  // namespace vdrig::probe

// The built-in scenes: their content (materials, bump, print, bands, markers, lights), phong_truth() against the
// radiance, area lights, and the registration markers' image positions.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <set>

#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {
namespace {

TEST(Scenes, PatchworkHasTheIssuesMaterials) {
  const Scene s = make_scene("patchwork").value();
  std::string why;
  ASSERT_TRUE(s.is_valid(&why)) << why;
  auto name_at = [&](double x, double y) { return s.materials[s.material_at(x, y)].name; };
  EXPECT_EQ(name_at(-225, -225), "red cloth");
  EXPECT_TRUE(s.materials[s.material_at(-225, -225)].ks.isZero());
  EXPECT_EQ(name_at(225, -225), "glossy plastic");
  EXPECT_EQ(name_at(0, 0), "paper");
  EXPECT_EQ(name_at(-225, 150), "brushed metal");
  EXPECT_EQ(name_at(225, 150), "printed paper");
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_EQ(s.lights[0].position_mm, Vec3d(1500, 1500, 2000));
  // The demo's region: the first Lambertian patch is the red cloth at [-400, -50]^2.
  for (const auto& p : s.patches)
    if (s.materials[p.material].ks.isZero()) {
      EXPECT_EQ(s.materials[p.material].name, "red cloth");
      EXPECT_EQ(p.x0_mm, -400);
      EXPECT_EQ(p.x1_mm, -50);
      break;
    }
  // Band of eight increasing shininess values from 2 to 500, left to right.
  std::vector<double> m;
  for (int k = 0; k < 8; ++k) m.push_back(s.materials[s.material_at(-350 + 100 * k, 345)].shininess);
  EXPECT_NEAR(m.front(), 2.0, 1e-9);
  EXPECT_NEAR(m.back(), 500.0, 1e-9);
  for (int k = 1; k < 8; ++k) EXPECT_GT(m[k], m[k - 1]);
}

TEST(Scenes, MetalNormalsArePerturbedDeterministically) {
  const Scene s = make_scene("patchwork").value();
  double max_tilt = 0, sum_tilt = 0;
  int n = 0;
  for (double x = -390; x < -60; x += 0.7)
    for (double y = 60; y < 240; y += 0.9) {
      const SurfacePoint sp = s.surface_at(x, y);
      ASSERT_NEAR(sp.normal.norm(), 1.0, 1e-12);
      EXPECT_EQ(sp.normal, s.surface_at(x, y).normal);
      const double tilt = std::acos(sp.normal.z());
      max_tilt = std::max(max_tilt, tilt), sum_tilt += tilt, ++n;
    }
  EXPECT_GT(rad_to_deg(max_tilt), 3.0);
  EXPECT_LT(rad_to_deg(max_tilt), 10.0);
  EXPECT_GT(rad_to_deg(sum_tilt / n), 1.0);
  EXPECT_EQ(s.surface_at(-225, -225).normal, Vec3d::UnitZ());  // cloth is flat
}

TEST(Scenes, PrintIsHighFrequencyTextLikeAlbedo) {
  const Scene s = make_scene("patchwork").value();
  const Material& print = s.materials[s.material_at(225, 150)];
  int ink = 0, total = 0, changes = 0;
  bool last = false;
  for (double y = 100; y < 200; y += 0.25)
    for (double x = 150; x < 300; x += 0.25) {
      const bool inked = s.surface_at(x, y).kd == print.ink_kd;
      ink += inked, ++total;
      changes += x > 150 && inked != last;
      last = inked;
    }
  const double fraction = double(ink) / total;
  EXPECT_GT(fraction, 0.1);
  EXPECT_LT(fraction, 0.5);
  // Detail at the millimetre scale: on average an ink edge every few mm along a line.
  const double edges_per_mm = changes / (400.0 * 150.0);
  EXPECT_GT(edges_per_mm, 0.15);
}

TEST(Scenes, PhongTruthReproducesTheRadianceOfEveryMaterial) {
  const Scene s = make_scene("patchwork").value();
  cv::RNG rng(11);
  std::set<int> materials;
  for (int i = 0; i < 20000; ++i) {
    const Vec3d p(rng.uniform(-490.0, 490.0), rng.uniform(-490.0, 490.0), 0.0);
    const auto truth = s.phong_truth(p);
    ASSERT_TRUE(truth) << p.transpose();
    const Vec3d v = direction_from_spherical(rng.uniform(0.0, 2 * kPi), rng.uniform(0.0, 1.5));
    const double rv = std::max(0.0, v.dot(truth->mirror_dir));
    const Vec3d model = truth->kd + truth->ks * std::pow(rv, truth->shininess);
    const Vec3d L = s.radiance(p, v);
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(L[c], model[c], 1e-12 + 1e-9 * model[c]);
    materials.insert(s.material_at(p.x(), p.y()));
  }
  EXPECT_EQ(materials.size(), s.materials.size());  // every material, markers included
  EXPECT_FALSE(make_scene("lights2")->phong_truth({0, 0, 0}).has_value());
  EXPECT_FALSE(make_scene("softbox")->phong_truth({0, 0, 0}).has_value());
}

TEST(Scenes, BandsAndLights2) {
  const Scene bands = make_scene("bands").value();
  std::set<double> m;
  for (int k = 0; k < 8; ++k) m.insert(bands.materials[bands.material_at(-350 + 100 * k, 0)].shininess);
  EXPECT_EQ(m.size(), 8u);
  EXPECT_NEAR(*m.begin(), 2.0, 1e-9);
  EXPECT_NEAR(*m.rbegin(), 500.0, 1e-9);
  const Scene two = make_scene("lights2").value();
  ASSERT_EQ(two.lights.size(), 2u);
  EXPECT_LT(two.lights[1].intensity.maxCoeff(), two.lights[0].intensity.maxCoeff());
  // Two highlights on the glossy patch: at each light's mirror direction the radiance has a local peak.
  const Vec3d p(225, -225, 0);
  for (const auto& light : two.lights) {
    const Vec3d r = mirror_direction((light.position_mm - p).normalized(), Vec3d::UnitZ());
    const double at = two.radiance(p, r).sum();
    for (double d : {-2.0, 2.0}) {
      const Vec3d off = direction_from_spherical(spherical_from_direction(r).azimuth_rad + deg_to_rad(d),
                                                 spherical_from_direction(r).zenith_rad);
      EXPECT_GT(at, two.radiance(p, off).sum());
    }
  }
  auto unknown = make_scene("nope");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("bands"), std::string::npos);
}

TEST(Scenes, AreaLightIsAStratifiedGridOfLambertianPointEmitters) {
  Scene s;
  s.name = "area";
  s.materials = {{"grey", Vec3d::Constant(0.5), Vec3d::Constant(0.3), 20.0}};
  AreaLight a{Vec3d(100, -200, 1500), Vec3d(300, 0, 0), Vec3d(0, -200, 0), Vec3d(2e6, 1e6, 5e5), 3};
  s.area_lights = {a};
  ASSERT_TRUE(s.is_valid(nullptr));
  ASSERT_LT(a.normal().z(), 0.0);  // faces the surface
  // The same light written out as nine point lights of intensity I cos(emit) / 9.
  Scene points = s;
  points.area_lights.clear();
  const Vec3d p(-50, 80, 0);
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      const Vec3d q = a.centre_mm + ((i + 0.5) / 3 - 0.5) * a.edge_u_mm + ((j + 0.5) / 3 - 0.5) * a.edge_v_mm;
      points.lights.push_back({q, a.intensity / 9.0 * (p - q).normalized().dot(a.normal())});
    }
  const Vec3d v = Vec3d(0.3, -0.2, 0.9).normalized();
  const Vec3d La = s.radiance(p, v), Lp = points.radiance(p, v);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(La[c], Lp[c], 1e-12 * Lp[c]);
  // A softbox lights more evenly than its point light, and ambient adds kd * ambient.
  const Scene soft = make_scene("softbox").value();
  ASSERT_EQ(soft.area_lights.size(), 1u);
  Scene dark = soft;
  dark.area_lights.clear();
  const Vec3d Ld = dark.radiance({0, 0, 0}, Vec3d::UnitZ());
  const Vec3d kd = soft.materials[0].kd;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(Ld[c], kd[c] * soft.ambient[c], 1e-12);
}

/// Area centroid of the image of a surface disc: projections of a fine grid of points over the disc weighted by
/// the image area each covers (the local Jacobian of surface -> image).
Vec2d projected_disc_centroid(const CameraModel& cam, const ViewPose& pose, const Vec3d& centre, double radius) {
  const double h = 0.25;
  Vec2d sum = Vec2d::Zero();
  double area = 0;
  for (double y = -radius; y <= radius; y += h)
    for (double x = -radius; x <= radius; x += h) {
      if (x * x + y * y > radius * radius) continue;
      const Vec3d q = centre + Vec3d(x, y, 0);
      const Vec2d a = cam.project(pose.to_camera(q));
      const Vec2d bx = cam.project(pose.to_camera(q + Vec3d(1e-3, 0, 0))) - a;
      const Vec2d by = cam.project(pose.to_camera(q + Vec3d(0, 1e-3, 0))) - a;
      const double jac = std::abs(bx.x() * by.y() - bx.y() * by.x());
      sum += jac * a, area += jac;
    }
  return sum / area;
}

/// Intensity-weighted centroid of a dark disc of radius 30 mm at surface point `centre`, measured in the image. The
/// region is the set of pixels whose centre sees the surface within 42 mm of the marker centre (the surface edge is
/// 50 mm away, and a square window would reach past it on oblique views); the weight is 1 - I / B, with B a plane
/// fitted to the ring 36..42 mm (the paper around the marker, whose irradiance varies slowly over it).
Vec2d dark_disc_centroid(const cv::Mat& green, const CameraModel& cam, const ViewPose& pose, const Vec3d& centre) {
  const Vec2d guess = cam.project(pose.to_camera(centre));
  const int half = 40;
  std::vector<std::pair<cv::Point, double>> region;  // pixel, distance on the surface (mm)
  const Vec3d C = pose.camera_centre();
  for (int y = std::max(0, int(guess.y()) - half); y <= std::min(cam.height - 1, int(guess.y()) + half); ++y)
    for (int x = std::max(0, int(guess.x()) - half); x <= std::min(cam.width - 1, int(guess.x()) + half); ++x) {
      const Vec3d ray = pose.R.transpose() * cam.pixel_ray({double(x), double(y)});
      const Vec3d p = C + (-C.z() / ray.z()) * ray;
      const double d = (p - centre).norm();
      if (d < 42.0) region.push_back({{x, y}, d});
    }
  cv::Mat A(0, 3, CV_64F), b(0, 1, CV_64F);
  for (const auto& [px, d] : region)
    if (d > 36.0) {
      A.push_back(cv::Mat(cv::Matx13d(1.0, px.x, px.y)));
      b.push_back(static_cast<double>(green.at<float>(px)));
    }
  cv::Mat plane;
  cv::solve(A, b, plane, cv::DECOMP_SVD);
  Vec2d sum = Vec2d::Zero();
  double wsum = 0;
  for (const auto& [px, d] : region) {
    const double B = plane.at<double>(0) + plane.at<double>(1) * px.x + plane.at<double>(2) * px.y;
    const double w = 1.0 - green.at<float>(px) / B;
    sum += w * Vec2d(px.x, px.y), wsum += w;
  }
  return sum / wsum;
}

TEST(Scenes, CornerMarkersLandWhereTheCameraModelProjectsThem) {
  const Scene s = make_scene("patchwork").value();
  const auto centres = s.marker_centres_mm();
  ASSERT_EQ(centres.size(), 4u);
  for (const auto& c : centres) {
    EXPECT_NEAR(std::abs(c.x()), 450.0, 1e-12);
    EXPECT_NEAR(std::abs(c.y()), 450.0, 1e-12);
    EXPECT_NEAR(s.materials[s.material_at(c.x(), c.y())].kd.maxCoeff(), 0.02, 1e-12);
    EXPECT_NE(s.material_at(c.x() + 31, c.y()), s.material_at(c.x(), c.y()));  // 30 mm radius
  }
  const CameraModel cam{320, 240, 400.0, 400.0, 161.3, 118.2, -0.08, 0.02, 0.0004, -0.0002, 0.0};
  double worst_vs_area = 0, worst_vs_centre = 0;
  const RayTable rays(cam, 6);
  for (const PanTilt pt :
       {PanTilt{0, 0}, PanTilt{deg_to_rad(25), deg_to_rad(35)}, PanTilt{deg_to_rad(-120), deg_to_rad(50)}}) {
    const ViewPose pose = rig::surface_pose({}, pt);
    const cv::Mat img = render_radiance(s, rays, pose);
    cv::Mat green;
    cv::extractChannel(img, green, 1);
    for (const auto& c : centres) {
      const Vec2d centre_px = cam.project(pose.to_camera(c));
      const Vec2d measured = dark_disc_centroid(green, cam, pose, c);
      const Vec2d area_centroid = projected_disc_centroid(cam, pose, c, 30.0);
      worst_vs_area = std::max(worst_vs_area, (measured - area_centroid).norm());
      worst_vs_centre = std::max(worst_vs_centre, (measured - centre_px).norm());
    }
  }
  std::printf(
      "marker centroids: worst %.4f px from the projected disc's area centroid, %.4f px from the projected "
      "centre\n",
      worst_vs_area, worst_vs_centre);
  EXPECT_LT(worst_vs_area, 0.05);
  EXPECT_LT(worst_vs_centre, 0.1);
}

}  // namespace
}  // namespace vdrig::sim

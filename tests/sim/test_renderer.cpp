// The renderer and the sensor model against closed forms: Lambertian radiance, the Phong lobe's peak, exposure
// codes, saturation, photon/read noise statistics and determinism.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {
namespace {

CameraModel small_camera() { return {200, 150, 250.0, 250.0, 99.5, 74.5, -0.08, 0.02, 0.0005, -0.0003, 0.0}; }

/// Surface point seen through the centre of pixel (x, y), found independently of the renderer's ray table.
std::optional<Vec3d> surface_point(const CameraModel& cam, const ViewPose& pose, int x, int y) {
  const Vec3d ray = pose.R.transpose() * cam.pixel_ray({double(x), double(y)});
  const Vec3d c = pose.camera_centre();
  if (ray.z() >= 0) return std::nullopt;
  return Vec3d(c + (-c.z() / ray.z()) * ray);
}

TEST(Renderer, LambertianPatchIsKdTimesIrradianceFromEveryDirection) {
  const Scene scene = make_scene("patchwork").value();
  const int cloth = scene.material_at(-225, -225);
  ASSERT_EQ(scene.materials[cloth].name, "red cloth");
  const Vec3d kd = scene.materials[cloth].kd;
  const PointLight& light = scene.lights.at(0);
  const CameraModel cam = small_camera();
  rig::RigGeometry geometry;
  int checked = 0;
  double worst = 0, max_zenith_deg = 0;
  for (const PanTilt pt :
       {PanTilt{0, 0}, PanTilt{deg_to_rad(30), deg_to_rad(40)}, PanTilt{deg_to_rad(200), deg_to_rad(70)},
        PanTilt{deg_to_rad(-100), deg_to_rad(55)}, PanTilt{deg_to_rad(135), deg_to_rad(78)}}) {
    const ViewPose pose = rig::surface_pose(geometry, pt);
    const cv::Mat img = render_radiance(scene, cam, pose, 2);
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const auto p = surface_point(cam, pose, x, y);
        // 60 mm inside the patch: the whole footprint of the pixel is cloth even at grazing views.
        if (!p || p->x() < -340 || p->x() > -110 || p->y() < -340 || p->y() > -110) continue;
        const Vec3d to_light = light.position_mm - *p;
        const double d2 = to_light.squaredNorm();
        const double cos_i = to_light.z() / std::sqrt(d2);
        const Vec3d expected = kd.cwiseProduct(light.intensity) * cos_i / d2;
        const cv::Vec3f got = img.at<cv::Vec3f>(y, x);
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(got[2 - c] / expected[c] - 1.0));
        max_zenith_deg = std::max(max_zenith_deg, rad_to_deg(std::acos(pose.view_direction(*p).z())));
        ++checked;
      }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
  std::printf("Lambertian: %d pixels, view zenith up to %.1f deg, worst relative error %.2e\n", checked, max_zenith_deg,
              worst);
  EXPECT_GT(checked, 500);
  EXPECT_GT(max_zenith_deg, 70.0);  // the check covers grazing views
  EXPECT_LT(worst, 0.005) << "over " << checked << " pixels";
}

TEST(Renderer, PhongLobePeaksInTheMirrorDirection) {
  const Scene scene = make_scene("patchwork").value();
  const Vec3d p(225, -225, 0);
  const auto truth = scene.phong_truth(p);
  ASSERT_TRUE(truth);
  // Sweep the hemisphere on a 0.25 degree grid: the brightest direction is the mirror direction.
  double best = -1;
  Vec3d best_dir = Vec3d::Zero();
  for (double zen = 0; zen < 89; zen += 0.25)
    for (double az = 0; az < 360; az += 0.25) {
      const Vec3d v = direction_from_spherical(deg_to_rad(az), deg_to_rad(zen));
      const double L = scene.radiance(p, v).sum();
      if (L > best) best = L, best_dir = v;
    }
  EXPECT_LT(rad_to_deg(angle_between(best_dir, truth->mirror_dir)), 0.3);
  const Vec3d at_mirror = scene.radiance(p, truth->mirror_dir);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(at_mirror[c], truth->kd[c] + truth->ks[c], 1e-9 * at_mirror[c]);

  // In an image: a pure specular plane's brightest pixel is where the light's mirror image, seen from the camera,
  // crosses the plane.
  Scene mirror;
  mirror.name = "mirror";
  mirror.materials = {{"specular", Vec3d::Zero(), Vec3d::Ones(), 500.0}};
  mirror.lights = {{Vec3d(500, 300, 2000), Vec3d::Constant(1e6)}};
  const CameraModel cam = small_camera();
  rig::RigGeometry geometry;
  const ViewPose pose = rig::surface_pose(geometry, {deg_to_rad(10), deg_to_rad(15)});
  const cv::Mat img = render_radiance(mirror, cam, pose, 2);
  cv::Mat green;
  cv::extractChannel(img, green, 1);
  cv::Point peak;
  cv::minMaxLoc(green, nullptr, nullptr, nullptr, &peak);
  const Vec3d C = pose.camera_centre();
  const Vec3d image_of_light(500, 300, -2000);
  const Vec3d specular_point = C + (C.z() / (C.z() - image_of_light.z())) * (image_of_light - C);
  const Vec2d expected = cam.project(pose.to_camera(specular_point));
  std::printf("specular peak at (%d, %d), expected (%.2f, %.2f)\n", peak.x, peak.y, expected.x(), expected.y());
  EXPECT_LT((Vec2d(peak.x, peak.y) - expected).norm(), 1.0) << "peak " << peak << " expected " << expected.transpose();
}

TEST(Renderer, RayTableRenderEqualsDirectRender) {
  const Scene scene = make_scene("patchwork").value();
  const CameraModel cam = small_camera();
  const ViewPose pose = rig::surface_pose({}, {deg_to_rad(40), deg_to_rad(35)});
  const RayTable table(cam, 2);
  EXPECT_TRUE(table.matches(cam, 2));
  EXPECT_FALSE(table.matches(cam, 3));
  EXPECT_EQ(cv::norm(render_radiance(scene, table, pose), render_radiance(scene, cam, pose, 2), cv::NORM_INF), 0.0);
}

SensorSettings linear_sensor(int bits) {
  SensorSettings s;
  s.response = ResponseCurve::linear(bits);
  return s;
}

TEST(Expose, LinearNoiselessCodesAreRoundedExposureAndSaturationClips) {
  cv::Mat radiance(60, 80, CV_32FC3);
  cv::RNG rng(7);
  rng.fill(radiance, cv::RNG::UNIFORM, 0.0, 1.3);  // about a quarter of the values saturate
  const double exposure_s = 0.5, gain = 2.0;       // X = radiance
  for (int bits : {8, 12}) {
    const cv::Mat codes = expose(radiance, exposure_s, gain, linear_sensor(bits), 0);
    const double max_code = (1 << bits) - 1;
    int saturated = 0, mismatches = 0;
    for (int y = 0; y < radiance.rows; ++y)
      for (int x = 0; x < radiance.cols; ++x)
        for (int c = 0; c < 3; ++c) {
          const double X = radiance.at<cv::Vec3f>(y, x)[c] * exposure_s * gain;
          const double expected = std::min(max_code, std::round(X * max_code));
          const double got = bits == 8 ? codes.at<cv::Vec3b>(y, x)[c] : codes.at<cv::Vec3w>(y, x)[c];
          saturated += X >= 1.0;
          mismatches += got != expected;
        }
    EXPECT_EQ(mismatches, 0) << bits << " bits";
    EXPECT_GT(saturated, 1000);
  }
}

/// Mean and variance of the electrons behind a flat exposure X with the given sensor (16-bit linear read-out).
std::pair<double, double> electron_stats(double X, const SensorSettings& sensor, uint64_t sequence) {
  const cv::Mat radiance(200, 200, CV_32FC3, cv::Scalar::all(X));
  const cv::Mat codes = expose(radiance, 1.0, 1.0, sensor, sequence);
  cv::Mat e;
  codes.reshape(1).convertTo(e, CV_64F, sensor.full_well_e / 65535.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(e, mean, stddev);
  return {mean[0], stddev[0] * stddev[0]};
}

TEST(Expose, PhotonNoiseIsPoissonAndReadNoiseAdds) {
  SensorSettings s = linear_sensor(16);
  s.full_well_e = 2000;
  const auto [mean, var] = electron_stats(0.25, s, 3);  // 500 electrons, 120000 samples
  EXPECT_NEAR(mean, 500.0, 0.5);                        // standard error 0.065
  EXPECT_NEAR(var / 500.0, 1.0, 0.03);                  // standard error of the variance about 0.4 %
  s.read_noise_e = 10;
  const auto [mean_r, var_r] = electron_stats(0.25, s, 3);
  EXPECT_NEAR(mean_r, 500.0, 0.5);
  EXPECT_NEAR(var_r / 600.0, 1.0, 0.03);
}

TEST(Expose, DeterministicPerSeedAndSequence) {
  SensorSettings s = linear_sensor(12);
  s.full_well_e = 5000;
  s.read_noise_e = 3;
  const cv::Mat radiance(50, 70, CV_32FC3, cv::Scalar(0.2, 0.4, 0.6));
  const cv::Mat a = expose(radiance, 1.0, 1.0, s, 5);
  EXPECT_EQ(cv::norm(a, expose(radiance, 1.0, 1.0, s, 5), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, expose(radiance, 1.0, 1.0, s, 6), cv::NORM_INF), 0.0);
  s.seed = 2;
  EXPECT_GT(cv::norm(a, expose(radiance, 1.0, 1.0, s, 5), cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace vdrig::sim

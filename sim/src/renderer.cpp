#include "vdrig/sim/renderer.hpp"

#include <opencv2/core/utility.hpp>
#include <random>

namespace vdrig::sim {

RayTable::RayTable(const CameraModel& camera, int samples_per_axis) : camera_(camera), n_(samples_per_axis) {
  VDRIG_CHECK(samples_per_axis >= 1, "at least one sample per pixel");
  const int n = n_;
  rays_.resize(static_cast<size_t>(camera.width) * camera.height * n * n);
  cv::parallel_for_(cv::Range(0, camera.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < camera.width; ++x) {
        cv::Vec3f* out = &rays_[(static_cast<size_t>(y) * camera.width + x) * n * n];
        for (int sy = 0; sy < n; ++sy)
          for (int sx = 0; sx < n; ++sx) {
            // Pixel (x, y) covers [x - 0.5, x + 0.5]: stratified sample centres.
            const Vec3d r = camera.pixel_ray({x - 0.5 + (sx + 0.5) / n, y - 0.5 + (sy + 0.5) / n});
            *out++ = cv::Vec3f(static_cast<float>(r.x()), static_cast<float>(r.y()), static_cast<float>(r.z()));
          }
      }
  });
}

bool RayTable::matches(const CameraModel& c, int samples_per_axis) const {
  const CameraModel& m = camera_;
  return n_ == samples_per_axis && m.width == c.width && m.height == c.height && m.fx == c.fx && m.fy == c.fy &&
         m.cx == c.cx && m.cy == c.cy && m.k1 == c.k1 && m.k2 == c.k2 && m.p1 == c.p1 && m.p2 == c.p2 && m.k3 == c.k3;
}

cv::Mat render_radiance(const Scene& scene, const CameraModel& camera, const ViewPose& pose, int samples_per_axis) {
  return render_radiance(scene, RayTable(camera, samples_per_axis), pose);
}

cv::Mat render_radiance(const Scene& scene, const RayTable& table, const ViewPose& pose) {
  const CameraModel& camera = table.camera();
  cv::Mat out(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  const Mat3d Rt = pose.R.transpose();
  const Vec3d centre = pose.camera_centre();  // surface frame
  const int n2 = table.samples_per_axis() * table.samples_per_axis();
  const double inv_n2 = 1.0 / n2;
  cv::parallel_for_(cv::Range(0, camera.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      auto* row = out.ptr<cv::Vec3f>(y);
      for (int x = 0; x < camera.width; ++x) {
        Vec3d sum = Vec3d::Zero();
        const cv::Vec3f* rays = table.rays(x, y);
        for (int k = 0; k < n2; ++k) {
          const Vec3d ray = Rt * Vec3d(rays[k][0], rays[k][1], rays[k][2]);  // surface frame
          if (std::abs(ray.z()) < 1e-12) continue;
          const double s = -centre.z() / ray.z();
          if (s <= 0) continue;
          const Vec3d p = centre + s * ray;
          sum += scene.radiance({p.x(), p.y(), 0.0}, -ray.normalized());
        }
        sum *= inv_n2;
        row[x] = cv::Vec3f(static_cast<float>(sum[2]), static_cast<float>(sum[1]), static_cast<float>(sum[0]));
      }
    }
  });
  return out;
}

bool SensorSettings::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (response.empty()) return fail("sensor needs a response curve");
  if (full_well_e < 0 || read_noise_e < 0) return fail("noise parameters must be >= 0");
  if (read_noise_e > 0 && full_well_e <= 0) return fail("read noise needs a full-well capacity");
  if (vignetting < 0 || vignetting >= 1) return fail("vignetting must be in [0, 1)");
  return true;
}

cv::Mat expose(const cv::Mat& radiance, double exposure_s, double gain, const SensorSettings& sensor,
               uint64_t sequence) {
  VDRIG_CHECK(radiance.type() == CV_32FC3, "radiance image must be CV_32FC3");
  const ResponseCurve& resp = sensor.response;
  const int depth = resp.bits() <= 8 ? CV_8U : CV_16U;
  cv::Mat out(radiance.size(), CV_MAKETYPE(depth, 3));
  const double scale = exposure_s * gain;
  const double max_code = resp.max_code();
  const double cx = radiance.cols / 2.0, cy = radiance.rows / 2.0, r_corner2 = cx * cx + cy * cy;
  cv::parallel_for_(cv::Range(0, radiance.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      // One generator per row, seeded by (seed, sequence, row): deterministic whatever the thread split.
      std::mt19937_64 rng(sensor.seed * 0x9E3779B97F4A7C15ull ^ (sequence << 20) ^ static_cast<uint64_t>(y));
      std::normal_distribution<double> read(0.0, sensor.read_noise_e);
      const auto* in = radiance.ptr<cv::Vec3f>(y);
      for (int x = 0; x < radiance.cols; ++x) {
        const double dx = x - cx, dy = y - cy;
        const double vig = 1.0 - sensor.vignetting * (dx * dx + dy * dy) / r_corner2;
        for (int c = 0; c < 3; ++c) {
          double X = in[x][c] * scale * vig;
          if (sensor.full_well_e > 0) {
            const double electrons = std::max(0.0, X * sensor.full_well_e);
            double e =
                electrons < 1e7 ? static_cast<double>(std::poisson_distribution<long>(electrons)(rng)) : electrons;
            if (sensor.read_noise_e > 0) e += read(rng);
            X = e / sensor.full_well_e;
          }
          const int channel_rgb = 2 - c;  // BGR storage, response indexed R, G, B
          const double code = std::clamp(std::round(resp.forward(channel_rgb, X)), 0.0, max_code);
          if (depth == CV_8U)
            out.ptr<cv::Vec3b>(y)[x][c] = static_cast<uchar>(code);
          else
            out.ptr<cv::Vec3w>(y)[x][c] = static_cast<uint16_t>(code);
        }
      }
    }
  });
  return out;
}

}  // namespace vdrig::sim

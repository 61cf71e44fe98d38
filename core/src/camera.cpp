#include "vdrig/core/camera.hpp"

#include <opencv2/core.hpp>

#include "vdrig/core/file_read.hpp"

namespace vdrig {

Vec2d CameraModel::distort(const Vec2d& u) const {
  const double x = u.x(), y = u.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

Vec2d CameraModel::undistort(const Vec2d& d) const {
  if (!has_distortion()) return d;
  // Fixed-point iteration as OpenCV's undistortPoints, but run to convergence rather than 5 steps.
  Vec2d u = d;
  for (int it = 0; it < 100; ++it) {
    const Vec2d e = distort(u) - d;
    u -= e;
    if (e.squaredNorm() < 1e-26) break;
  }
  return u;
}

Vec2d CameraModel::project(const Vec3d& p) const {
  const Vec2d d = distort({p.x() / p.z(), p.y() / p.z()});
  return {fx * d.x() + cx, fy * d.y() + cy};
}

Vec3d CameraModel::pixel_ray(const Vec2d& pixel) const {
  const Vec2d u = undistort({(pixel.x() - cx) / fx, (pixel.y() - cy) / fy});
  return Vec3d(u.x(), u.y(), 1.0).normalized();
}

bool CameraModel::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (width <= 0 || height <= 0) return fail("image size must be positive");
  if (!(fx > 0) || !(fy > 0)) return fail("focal lengths must be positive");
  if (cx < 0 || cx > width || cy < 0 || cy > height) return fail("principal point outside the image");
  return true;
}

Result<CameraModel> CameraModel::load_yaml(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) return make_error(ErrorCode::kNotFound, "no camera file " + path.string());
  VDRIG_TRY(check_regular_file(path));  // cv::FileStorage would wait on a FIFO
  try {
    cv::FileStorage fs(path.string(), cv::FileStorage::READ);
    if (!fs.isOpened()) return make_error(ErrorCode::kCorrupt, "cannot parse " + path.string());
    cv::Mat K, D;
    fs["camera_matrix"] >> K;
    fs["distortion_coefficients"] >> D;
    if (K.rows != 3 || K.cols != 3)
      return make_error(ErrorCode::kCorrupt, path.string() + ": camera_matrix is not 3x3");
    CameraModel m;
    fs["image_width"] >> m.width;
    fs["image_height"] >> m.height;
    K.convertTo(K, CV_64F);
    m.fx = K.at<double>(0, 0);
    m.fy = K.at<double>(1, 1);
    m.cx = K.at<double>(0, 2);
    m.cy = K.at<double>(1, 2);
    if (!D.empty()) {
      D.convertTo(D, CV_64F);
      D = D.reshape(1, 1);
      const double* d = D.ptr<double>();
      const int n = D.cols;
      m.k1 = n > 0 ? d[0] : 0;
      m.k2 = n > 1 ? d[1] : 0;
      m.p1 = n > 2 ? d[2] : 0;
      m.p2 = n > 3 ? d[3] : 0;
      m.k3 = n > 4 ? d[4] : 0;
    }
    std::string why;
    if (!m.is_valid(&why)) return make_error(ErrorCode::kCorrupt, path.string() + ": " + why);
    return m;
  } catch (const cv::Exception& e) {
    return make_error(ErrorCode::kCorrupt, path.string() + ": " + e.what());
  }
}

Status CameraModel::save_yaml(const std::filesystem::path& path, double avg_reprojection_error_px,
                              const std::function<void(cv::FileStorage&)>& extras) const {
  try {
    cv::FileStorage fs(path.string(), cv::FileStorage::WRITE);
    if (!fs.isOpened()) return make_error(ErrorCode::kIo, "cannot write " + path.string());
    fs << "format_version" << 1;
    fs << "image_width" << width << "image_height" << height;
    cv::Mat K = (cv::Mat_<double>(3, 3) << fx, 0, cx, 0, fy, cy, 0, 0, 1);
    cv::Mat D = (cv::Mat_<double>(5, 1) << k1, k2, p1, p2, k3);
    fs << "camera_matrix" << K << "distortion_coefficients" << D;
    if (avg_reprojection_error_px >= 0) fs << "avg_reprojection_error" << avg_reprojection_error_px;
    if (extras) extras(fs);
    return Status::ok();
  } catch (const cv::Exception& e) {
    return make_error(ErrorCode::kIo, path.string() + ": " + e.what());
  }
}

}  // namespace vdrig

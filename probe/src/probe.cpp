#include "vdrig/probe/probe.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <string>

#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::probe {
namespace {

constexpr const char* kVersionAttr = "vdrig.probe.version";
constexpr const char* kLayoutAttr = "vdrig.probe.layout";
constexpr int kFileVersion = 1;

std::string pose_attr(const char* what, int k) { return std::string("vdrig.probe.") + what + "." + std::to_string(k); }

// Bilinear sample of a single- or three-channel float map at continuous pixel coordinates (x, y) measured so that
// pixel centres sit at integers; wraps x (azimuth), clamps y (zenith).
template <typename Pixel>
Pixel bilinear(const cv::Mat& map, double x, double y) {
  const int W = map.cols, H = map.rows;
  y = std::clamp(y, 0.0, static_cast<double>(H - 1));
  const double xf = std::floor(x), yf = std::floor(y);
  const double ax = x - xf, ay = y - yf;
  int x0 = static_cast<int>(xf) % W;
  if (x0 < 0) x0 += W;
  const int x1 = (x0 + 1) % W;
  const int y0 = static_cast<int>(yf), y1 = std::min(y0 + 1, H - 1);
  const Pixel a = map.at<Pixel>(y0, x0), b = map.at<Pixel>(y0, x1), c = map.at<Pixel>(y1, x0),
              d = map.at<Pixel>(y1, x1);
  const double wa = (1 - ax) * (1 - ay), wb = ax * (1 - ay), wc = (1 - ax) * ay, wd = ax * ay;
  return a * static_cast<float>(wa) + b * static_cast<float>(wb) + c * static_cast<float>(wc) +
         d * static_cast<float>(wd);
}

// Continuous pixel coordinates (centres at integers) of a direction.
void direction_to_pixel(const Vec3d& dir, int W, int H, double* x, double* y) {
  const SphericalDir s = spherical_from_direction(dir);
  *x = s.azimuth_rad / (2.0 * kPi) * W - 0.5;
  *y = s.zenith_rad / kPi * H - 0.5;
}

}  // namespace

Probe make_probe(int height) {
  VDRIG_CHECK(height >= 1, "a probe needs at least one row");
  Probe p;
  p.radiance = cv::Mat(height, 2 * height, CV_32FC3, cv::Scalar::all(0));
  return p;
}

Result<Probe> load_probe(const std::filesystem::path& path, const LoadOptions& options, FileAzimuth* file_layout) {
  auto log = vdrig::log::get("probe");
  if (options.width != 0 && (options.width < 2 || options.width % 2 != 0))
    return make_error(ErrorCode::kInvalidArgument, "probe width must be even and >= 2 (or 0 to keep the file's), got " +
                                                       std::to_string(options.width));
  if (!std::filesystem::exists(path))
    return make_error(ErrorCode::kNotFound, "light probe " + path.string() + " does not exist");
  auto exr = read_exr(path);
  if (!exr) return make_error(exr.error().code, "light probe: " + exr.error().message);
  const ExrImage& im = exr.value();
  const int ch[3] = {im.find("B"), im.find("G"), im.find("R")};  // the radiance Mat's order
  if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0)
    return make_error(ErrorCode::kCorrupt, "light probe " + path.string() + " has no R, G and B channels");
  const int W = im.width, H = im.height;
  if (H < 1 || W != 2 * H)
    return make_error(ErrorCode::kInvalidArgument, "light probe " + path.string() +
                                                       " is not a 2:1 latitude-longitude map (width must be twice "
                                                       "the height), got " +
                                                       std::to_string(W) + " x " + std::to_string(H));
  const bool ours = im.number_attributes.count(kVersionAttr) > 0;
  if (ours && im.number_attributes.at(kVersionAttr) > kFileVersion)
    return make_error(ErrorCode::kCorrupt, "light probe " + path.string() + " has format version " +
                                               std::to_string(im.number_attributes.at(kVersionAttr)) +
                                               ", newer than this build reads (" + std::to_string(kFileVersion) + ")");
  const bool mirror = !ours && options.azimuth == FileAzimuth::kPanorama;
  if (file_layout) *file_layout = mirror ? FileAzimuth::kPanorama : FileAzimuth::kDesignNotes;

  Probe p = make_probe(H);
  long clamped = 0;
  for (int j = 0; j < H; ++j)
    for (int c = 0; c < W; ++c) {
      const int i = mirror ? ((W / 2 - 1 - c) % W + W) % W : c;
      cv::Vec3f& out = p.radiance.at<cv::Vec3f>(j, i);
      for (int k = 0; k < 3; ++k) {
        const float v = im.channels[ch[k]].at<float>(j, c);
        if (!std::isfinite(v))
          return make_error(ErrorCode::kCorrupt, "light probe " + path.string() + " has a non-finite value at (" +
                                                     std::to_string(c) + ", " + std::to_string(j) + ")");
        if (v < 0) ++clamped;
        out[k] = std::max(v, 0.0f);
      }
    }
  if (clamped > 0) log->debug("{}: clamped {} negative values (compression ringing) to 0", path.string(), clamped);

  if (ours) {
    for (int k = 0; k < 3; ++k) {
      auto it = im.number_attributes.find(pose_attr("position_mm", k));
      if (it != im.number_attributes.end()) p.position_mm[k] = it->second;
    }
    for (int k = 0; k < 9; ++k) {
      auto it = im.number_attributes.find(pose_attr("rotation", k));
      if (it != im.number_attributes.end()) p.rotation(k / 3, k % 3) = it->second;
    }
    const int z = im.find("Z");
    if (z >= 0) p.depth_mm = im.channels[z].clone();
  }
  log->debug("loaded {}: {} x {}{}", path.string(), W, H, mirror ? " (panorama azimuth, mirrored)" : "");
  if (options.width > 0 && options.width != W) return resample(p, options.width);
  return p;
}

Status save_probe(const std::filesystem::path& path, const Probe& probe, FileAzimuth layout) {
  ExrImage im;
  if (layout == FileAzimuth::kPanorama) {
    // load_probe's mapping i = (W / 2 - 1 - c) mod W is its own inverse: file column c = (W / 2 - 1 - i) mod W.
    const int W = probe.width();
    cv::Mat mirrored(probe.radiance.size(), CV_32FC3);
    for (int c = 0; c < W; ++c) probe.radiance.col(((W / 2 - 1 - c) % W + W) % W).copyTo(mirrored.col(c));
    im.add_bgr(mirrored);
    return write_exr(path, im);
  }
  im.add_bgr(probe.radiance);
  if (probe.has_depth()) im.add("Z", probe.depth_mm);
  im.number_attributes[kVersionAttr] = kFileVersion;
  im.string_attributes[kLayoutAttr] = "design-notes";
  for (int k = 0; k < 3; ++k) im.number_attributes[pose_attr("position_mm", k)] = probe.position_mm[k];
  for (int k = 0; k < 9; ++k) im.number_attributes[pose_attr("rotation", k)] = probe.rotation(k / 3, k % 3);
  return write_exr(path, im);
}

Probe resample(const Probe& probe, int width) {
  VDRIG_CHECK(width >= 2 && width % 2 == 0, "probe width must be even and >= 2");
  Probe out;
  out.position_mm = probe.position_mm;
  out.rotation = probe.rotation;
  const int W = width, H = width / 2;
  if (W == probe.width()) {
    out.radiance = probe.radiance.clone();
    out.depth_mm = probe.depth_mm.clone();
    return out;
  }
  if (W < probe.width() && probe.width() % W == 0) {
    // Integer factor: each output pixel is the solid-angle-weighted mean of the f x f block it covers, so the
    // power (sum of L x solid angle) is kept exactly; a plain box mean would over-weight the block's polar rows.
    const int f = probe.width() / W, Wi = probe.width(), Hi = probe.height();
    out.radiance = cv::Mat(H, W, CV_32FC3);
    if (probe.has_depth()) out.depth_mm = cv::Mat(H, W, CV_32FC1);
    for (int j = 0; j < H; ++j)
      for (int i = 0; i < W; ++i) {
        Rgb sum = Rgb::Zero();
        double depth = 0, weight = 0;
        for (int jj = j * f; jj < (j + 1) * f; ++jj) {
          const double sa = latlong_pixel_solid_angle(jj, Wi, Hi);
          for (int ii = i * f; ii < (i + 1) * f; ++ii) {
            sum += sa * probe.pixel(ii, jj);
            if (probe.has_depth()) depth += sa * probe.depth_mm.at<float>(jj, ii);
          }
          weight += f * sa;
        }
        out.set_pixel(i, j, sum / weight);
        if (probe.has_depth()) out.depth_mm.at<float>(j, i) = static_cast<float>(depth / weight);
      }
    return out;
  }
  if (W < probe.width()) {
    // Other factors: OpenCV's area averaging (box weights; the rows' solid-angle variation across one output pixel
    // is neglected).
    cv::resize(probe.radiance, out.radiance, cv::Size(W, H), 0, 0, cv::INTER_AREA);
    if (probe.has_depth()) cv::resize(probe.depth_mm, out.depth_mm, cv::Size(W, H), 0, 0, cv::INTER_AREA);
    return out;
  }
  out.radiance = cv::Mat(H, W, CV_32FC3);
  if (probe.has_depth()) out.depth_mm = cv::Mat(H, W, CV_32FC1);
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      double x, y;
      direction_to_pixel(latlong_direction(i, j, W, H), probe.width(), probe.height(), &x, &y);
      out.radiance.at<cv::Vec3f>(j, i) = bilinear<cv::Vec3f>(probe.radiance, x, y);
      if (probe.has_depth()) out.depth_mm.at<float>(j, i) = bilinear<float>(probe.depth_mm, x, y);
    }
  return out;
}

Rgb radiance_at(const Probe& probe, const Vec3d& dir) {
  double x, y;
  direction_to_pixel(dir, probe.width(), probe.height(), &x, &y);
  return from_bgr(bilinear<cv::Vec3f>(probe.radiance, x, y));
}

Rgb total_power(const Probe& probe) {
  const int W = probe.width(), H = probe.height();
  Rgb sum = Rgb::Zero();
  for (int j = 0; j < H; ++j) {
    Rgb row = Rgb::Zero();
    for (int i = 0; i < W; ++i) row += probe.pixel(i, j);
    sum += row * latlong_pixel_solid_angle(j, W, H);
  }
  return sum;
}

double total_solid_angle(const Probe& probe) {
  double sum = 0;
  for (int j = 0; j < probe.height(); ++j)
    sum += probe.width() * latlong_pixel_solid_angle(j, probe.width(), probe.height());
  return sum;
}

BrightestPixel brightest_pixel(const Probe& probe) {
  BrightestPixel best;
  double best_y = -1;
  for (int j = 0; j < probe.height(); ++j)
    for (int i = 0; i < probe.width(); ++i) {
      const Rgb c = probe.pixel(i, j);
      const double y = luminance(c);
      if (y > best_y) {
        best_y = y;
        best.column = i;
        best.row = j;
        best.radiance = c;
      }
    }
  best.direction = latlong_direction(best.column, best.row, probe.width(), probe.height());
  return best;
}

IrradianceIntegrator::IrradianceIntegrator(const Probe& probe, int max_width) {
  const Probe small = max_width > 0 && probe.width() > max_width ? resample(probe, max_width) : Probe{};
  const Probe& p = small.radiance.empty() ? probe : small;
  const int W = p.width(), H = p.height();
  width_ = W;
  dirs_.reserve(3 * static_cast<size_t>(W) * H);
  weighted_.reserve(3 * static_cast<size_t>(W) * H);
  for (int j = 0; j < H; ++j) {
    const double sa = latlong_pixel_solid_angle(j, W, H);
    for (int i = 0; i < W; ++i) {
      const Rgb c = p.pixel(i, j) * sa;
      if (c.isZero()) continue;  // black pixels contribute nothing
      const Vec3d d = latlong_direction(i, j, W, H);
      for (int k = 0; k < 3; ++k) {
        dirs_.push_back(static_cast<float>(d[k]));
        weighted_.push_back(static_cast<float>(c[k]));
      }
    }
  }
}

IrradianceIntegrator::IrradianceIntegrator(const std::vector<Vec3d>& directions,
                                           const std::vector<Rgb>& radiance_times_sr) {
  VDRIG_CHECK(directions.size() == radiance_times_sr.size(), "one radiance per direction");
  width_ = 0;
  for (size_t p = 0; p < directions.size(); ++p) {
    if (radiance_times_sr[p].isZero()) continue;
    for (int k = 0; k < 3; ++k) {
      dirs_.push_back(static_cast<float>(directions[p][k]));
      weighted_.push_back(static_cast<float>(radiance_times_sr[p][k]));
    }
  }
}

Rgb IrradianceIntegrator::irradiance(const Vec3d& normal) const {
  const float nx = static_cast<float>(normal.x()), ny = static_cast<float>(normal.y()),
              nz = static_cast<float>(normal.z());
  // Float products summed in short float chunks, chunks summed in double: ~1e-6 relative over 0.5 M pixels, and the
  // inner loop vectorises.
  double r = 0, g = 0, b = 0;
  const size_t n = dirs_.size() / 3;
  constexpr size_t kChunk = 256;
  for (size_t start = 0; start < n; start += kChunk) {
    float cr = 0, cg = 0, cb = 0;
    const size_t end = std::min(n, start + kChunk);
    for (size_t p = start; p < end; ++p) {
      const float c = std::max(0.0f, nx * dirs_[3 * p] + ny * dirs_[3 * p + 1] + nz * dirs_[3 * p + 2]);
      cr += c * weighted_[3 * p];
      cg += c * weighted_[3 * p + 1];
      cb += c * weighted_[3 * p + 2];
    }
    r += cr;
    g += cg;
    b += cb;
  }
  return {r, g, b};
}

std::vector<Vec3d> fibonacci_directions(int count) {
  std::vector<Vec3d> out;
  out.reserve(count);
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < count; ++k) {
    const double z = 1.0 - (2.0 * k + 1.0) / count;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    out.emplace_back(r * std::cos(golden * k), r * std::sin(golden * k), z);
  }
  return out;
}

}  // namespace vdrig::probe

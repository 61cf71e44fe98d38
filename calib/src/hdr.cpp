#include "vdrig/calib/hdr.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core/utility.hpp>
#include <sstream>
#include <string>

#include "vdrig/core/log.hpp"

namespace vdrig::calib {

namespace {

std::string frame_str(size_t i) { return "frame " + std::to_string(i); }

std::string join_numbers(const std::vector<double>& v) {
  std::string s;
  char buf[32];
  for (size_t i = 0; i < v.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.9g", v[i]);
    if (i) s += ',';
    s += buf;
  }
  return s;
}

Result<std::vector<double>> parse_numbers(const std::string& s, const char* what) {
  std::vector<double> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      out.push_back(std::stod(item));
    } catch (const std::exception&) {
      return make_error(ErrorCode::kCorrupt, std::string("HDR attribute ") + what + ": bad number '" + item + "'");
    }
  }
  return out;
}

// Per-frame tables indexed by code: numerator w(z) inverse(z) / t and denominator w(z), per channel.
struct MergeTables {
  int table_size = 0;
  std::vector<float> num;                 // [frame][channel][code]
  std::vector<float> den;                 // [frame][channel][code]
  std::vector<float> fallback_saturated;  // [image channel]: inverse(max) / t_shortest
  std::vector<float> fallback_black;      // [image channel]: inverse(0) / t_longest
  const float* num_of(size_t frame, int c) const {
    return num.data() + (frame * 3 + static_cast<size_t>(c)) * static_cast<size_t>(table_size);
  }
  const float* den_of(size_t frame, int c) const {
    return den.data() + (frame * 3 + static_cast<size_t>(c)) * static_cast<size_t>(table_size);
  }
};

template <typename T>
void merge_rows(const std::vector<const cv::Mat*>& images, const MergeTables& tab, size_t shortest, int max_code,
                const cv::Range& rows, cv::Mat& radiance, cv::Mat& mask) {
  const int width = radiance.cols;
  const size_t n = static_cast<size_t>(width) * 3;
  std::vector<float> num(n), den(n);
  const T* shortest_row = nullptr;
  for (int y = rows.start; y < rows.end; ++y) {
    std::fill(num.begin(), num.end(), 0.0f);
    std::fill(den.begin(), den.end(), 0.0f);
    for (size_t j = 0; j < images.size(); ++j) {
      const T* p = images[j]->ptr<T>(y);
      const float* n0 = tab.num_of(j, 0);
      const float* n1 = tab.num_of(j, 1);
      const float* n2 = tab.num_of(j, 2);
      const float* d0 = tab.den_of(j, 0);
      const float* d1 = tab.den_of(j, 1);
      const float* d2 = tab.den_of(j, 2);
      for (size_t i = 0; i < n; i += 3) {
        const T z0 = p[i], z1 = p[i + 1], z2 = p[i + 2];
        num[i] += n0[z0];
        num[i + 1] += n1[z1];
        num[i + 2] += n2[z2];
        den[i] += d0[z0];
        den[i + 1] += d1[z1];
        den[i + 2] += d2[z2];
      }
    }
    shortest_row = images[shortest]->ptr<T>(y);
    float* out = radiance.ptr<float>(y);
    uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < width; ++x) {
      uint8_t flags = kHdrValid;
      for (int c = 0; c < 3; ++c) {
        const size_t i = static_cast<size_t>(x) * 3 + static_cast<size_t>(c);
        if (den[i] > 0.0f) {
          out[i] = num[i] / den[i];
        } else if (static_cast<int>(shortest_row[i]) >= max_code) {
          // Clipped high even in the shortest exposure: the best we know is a lower bound from that one.
          out[i] = tab.fallback_saturated[c];
          flags |= kHdrSaturated;
        } else {
          out[i] = tab.fallback_black[c];
          flags |= kHdrBlack;
        }
      }
      m[x] = flags;
    }
  }
}

}  // namespace

float hdr_hat_weight(int code, int max_code) {
  if (code <= 0 || code >= max_code) return 0.0f;
  const float half = 0.5f * static_cast<float>(max_code);
  return static_cast<float>(std::min(code, max_code - code)) / half;
}

Status validate_bracket(std::span<const Frame> frames, const ResponseCurve& response, int min_frames) {
  const auto bad = [](const std::string& m) { return Status(make_error(ErrorCode::kInvalidArgument, m)); };
  if (frames.empty()) return bad("empty bracket: at least one frame is needed");
  if (static_cast<int>(frames.size()) < min_frames)
    return bad("bracket has " + std::to_string(frames.size()) + " frame(s), at least " + std::to_string(min_frames) +
               " needed");
  const Frame& f0 = frames[0];
  for (size_t i = 0; i < frames.size(); ++i) {
    const Frame& f = frames[i];
    if (f.image.empty()) return bad(frame_str(i) + " has no image");
    if (f.image.type() != CV_8UC3 && f.image.type() != CV_16UC3)
      return bad(frame_str(i) + " is of type " + cv::typeToString(f.image.type()) + ", want CV_8UC3 or CV_16UC3");
    if (f.image.size() != f0.image.size())
      return bad(frame_str(i) + " is " + std::to_string(f.image.cols) + "x" + std::to_string(f.image.rows) +
                 ", frame 0 is " + std::to_string(f0.image.cols) + "x" + std::to_string(f0.image.rows));
    if (f.image.type() != f0.image.type())
      return bad(frame_str(i) + " is " + cv::typeToString(f.image.type()) + ", frame 0 is " +
                 cv::typeToString(f0.image.type()));
    const int container_bits = f.image.depth() == CV_8U ? 8 : 16;
    if (f.bits < 1 || f.bits > container_bits)
      return bad(frame_str(i) + " claims " + std::to_string(f.bits) + " bits in a " + std::to_string(container_bits) +
                 "-bit image");
    if (f.bits != f0.bits)
      return bad(frame_str(i) + " has " + std::to_string(f.bits) + " bits, frame 0 has " + std::to_string(f0.bits));
    if (!(f.exposure_s > 0.0) || !std::isfinite(f.exposure_s))
      return bad(frame_str(i) + " has no valid exposure time (exposure_s = " + std::to_string(f.exposure_s) + ")");
    if (!(f.gain > 0.0) || !std::isfinite(f.gain))
      return bad(frame_str(i) + " has no valid gain (gain = " + std::to_string(f.gain) + ")");
  }
  for (size_t i = 0; i < frames.size(); ++i)
    for (size_t k = i + 1; k < frames.size(); ++k) {
      const double a = frames[i].exposure_s * frames[i].gain, b = frames[k].exposure_s * frames[k].gain;
      if (std::abs(a - b) <= 1e-9 * std::max(a, b))
        return bad("duplicate exposure: " + frame_str(i) + " and " + frame_str(k) +
                   " both have exposure_s * gain = " + std::to_string(a));
    }
  if (frames.size() >= 3) {
    const double first_step = frames[1].exposure_s * frames[1].gain - frames[0].exposure_s * frames[0].gain;
    for (size_t i = 2; i < frames.size(); ++i) {
      const double step = frames[i].exposure_s * frames[i].gain - frames[i - 1].exposure_s * frames[i - 1].gain;
      if ((step > 0) != (first_step > 0))
        return bad("exposures are not monotonic: " + frame_str(i) + " breaks the order (sort the bracket by exposure)");
    }
  }
  if (!response.empty() && response.bits() != f0.bits)
    return bad("response curve has " + std::to_string(response.bits()) + " bits, frames have " +
               std::to_string(f0.bits));
  return Status::ok();
}

Result<HdrImage> merge_hdr(std::span<const Frame> frames, const ResponseCurve& response_in) {
  VDRIG_TRY(validate_bracket(frames, response_in, 1));
  const int bits = frames[0].bits;
  const ResponseCurve response = response_in.empty() ? ResponseCurve::linear(bits) : response_in;
  const int max_code = response.max_code();
  const bool is8 = frames[0].image.depth() == CV_8U;

  MergeTables tab;
  tab.table_size = is8 ? 256 : 65536;
  const size_t ts = static_cast<size_t>(tab.table_size);
  tab.num.assign(frames.size() * 3 * ts, 0.0f);
  tab.den.assign(frames.size() * 3 * ts, 0.0f);
  size_t shortest = 0, longest = 0;
  std::vector<double> t(frames.size());
  for (size_t j = 0; j < frames.size(); ++j) {
    t[j] = frames[j].exposure_s * frames[j].gain;
    if (t[j] < t[shortest]) shortest = j;
    if (t[j] > t[longest]) longest = j;
  }
  for (int c = 0; c < 3; ++c) {
    const auto& inv = response.inverse_table(2 - c);  // images are B, G, R; the response is indexed R, G, B
    for (size_t z = 0; z < ts; ++z) {
      const int code = static_cast<int>(z);
      const float w = hdr_hat_weight(code, max_code);
      const double x = inv[static_cast<size_t>(std::min(code, max_code))];
      for (size_t j = 0; j < frames.size(); ++j) {
        // The same weight for every frame; stored per frame so the inner loop reads one table pair per frame.
        tab.den[(j * 3 + static_cast<size_t>(c)) * ts + z] = w;
        tab.num[(j * 3 + static_cast<size_t>(c)) * ts + z] = static_cast<float>(w * x / t[j]);
      }
    }
    tab.fallback_saturated.push_back(static_cast<float>(inv[static_cast<size_t>(max_code)] / t[shortest]));
    tab.fallback_black.push_back(static_cast<float>(inv[0] / t[longest]));
  }

  HdrImage out;
  out.bits = bits;
  out.radiance.create(frames[0].image.size(), CV_32FC3);
  out.mask.create(frames[0].image.size(), CV_8UC1);
  for (const auto& f : frames) {
    out.exposures_s.push_back(f.exposure_s);
    out.gains.push_back(f.gain);
  }
  std::vector<const cv::Mat*> images;
  for (const auto& f : frames) images.push_back(&f.image);

  // Stripes of ~16 rows keep per-task overhead small while still balancing across threads.
  const int rows = out.radiance.rows;
  const double stripes = std::max(1.0, rows / 16.0);
  cv::parallel_for_(
      cv::Range(0, rows),
      [&](const cv::Range& r) {
        if (is8)
          merge_rows<uint8_t>(images, tab, shortest, max_code, r, out.radiance, out.mask);
        else
          merge_rows<uint16_t>(images, tab, shortest, max_code, r, out.radiance, out.mask);
      },
      stripes);
  return out;
}

ExrImage HdrImage::to_exr() const {
  VDRIG_CHECK(radiance.type() == CV_32FC3, "HdrImage radiance must be CV_32FC3");
  VDRIG_CHECK(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == radiance.size()),
              "HdrImage mask must be CV_8UC1 of the radiance's size");
  ExrImage exr;
  exr.add_bgr(radiance);
  cv::Mat m;
  if (mask.empty())
    m = cv::Mat::zeros(radiance.size(), CV_32FC1);
  else
    mask.convertTo(m, CV_32F);
  exr.add("mask", m);
  exr.number_attributes["vdrig.hdr.format_version"] = kFormatVersion;
  exr.number_attributes["vdrig.hdr.bits"] = bits;
  exr.string_attributes["vdrig.hdr.exposures_s"] = join_numbers(exposures_s);
  exr.string_attributes["vdrig.hdr.gains"] = join_numbers(gains);
  return exr;
}

Result<HdrImage> HdrImage::from_exr(const ExrImage& exr) {
  const int r = exr.find("R"), g = exr.find("G"), b = exr.find("B");
  if (r < 0 || g < 0 || b < 0) return make_error(ErrorCode::kCorrupt, "HDR image lacks one of the R, G, B channels");
  if (auto it = exr.number_attributes.find("vdrig.hdr.format_version");
      it != exr.number_attributes.end() && it->second > kFormatVersion)
    return make_error(ErrorCode::kUnsupported,
                      "HDR image format version " + std::to_string(it->second) + " is newer than this build reads");
  HdrImage out;
  cv::Mat planes[3] = {exr.channels[static_cast<size_t>(b)], exr.channels[static_cast<size_t>(g)],
                       exr.channels[static_cast<size_t>(r)]};
  cv::merge(planes, 3, out.radiance);
  if (const int m = exr.find("mask"); m >= 0)
    exr.channels[static_cast<size_t>(m)].convertTo(out.mask, CV_8U);  // rounds to nearest
  else
    out.mask = cv::Mat::zeros(out.radiance.size(), CV_8UC1);
  if (auto it = exr.number_attributes.find("vdrig.hdr.bits"); it != exr.number_attributes.end())
    out.bits = static_cast<int>(it->second);
  if (auto it = exr.string_attributes.find("vdrig.hdr.exposures_s"); it != exr.string_attributes.end()) {
    auto v = parse_numbers(it->second, "exposures_s");
    if (!v) return v.error();
    out.exposures_s = std::move(*v);
  }
  if (auto it = exr.string_attributes.find("vdrig.hdr.gains"); it != exr.string_attributes.end()) {
    auto v = parse_numbers(it->second, "gains");
    if (!v) return v.error();
    out.gains = std::move(*v);
  }
  return out;
}

Status write_hdr_exr(const std::filesystem::path& path, const HdrImage& image, ExrPixelType type) {
  if (image.radiance.type() != CV_32FC3 || image.radiance.empty())
    return make_error(ErrorCode::kInvalidArgument, "HDR image to write is empty or not CV_32FC3");
  return write_exr(path, image.to_exr(), type);
}

Result<HdrImage> read_hdr_exr(const std::filesystem::path& path) {
  auto exr = read_exr(path);
  if (!exr) return exr.error();
  auto img = HdrImage::from_exr(*exr);
  if (!img) return make_error(img.error().code, path.string() + ": " + img.error().message);
  return img;
}

}  // namespace vdrig::calib

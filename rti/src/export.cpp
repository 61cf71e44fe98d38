#include "vdrig/rti/export.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <functional>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/core.hpp>

#include "jpeg_444.hpp"
#include "relight_layout.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;
using fitting::ParameterMap;

constexpr double kCodes = 255.0;

/// Range of a set of values, widened when empty so that scale is never 0.
struct Range {
  double lo = 0, hi = 0;
  void add(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  double span() const { return hi - lo > 1e-12 ? hi - lo : 1e-12; }
};

uint8_t to_byte(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

std::string format_float(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

/// Per-texel coefficients K x 3 (rows = terms, columns = R G B) of the map, in its file's units.
using TexelCoefficients = std::function<Eigen::MatrixXd(int s, int t)>;

Status write_ptm(const ParameterMap& map, bool rgb, const fs::path& out) {
  const int S = map.texels_s(), T = map.texels_t();
  // Texel i's coefficients in code units, a[6 c + k] (RGB), or L' in a[k] and the colour bytes (LRGB). Computed
  // twice (the ranges, then the bytes) rather than kept: 18 doubles per texel were 9 MB at 256 x 256, the largest
  // allocation of `vdrig rti fit STACK --out x.ptm`.
  std::vector<double> p;
  double a[18] = {};
  uint8_t colour[3] = {};
  const auto texel = [&](size_t i) {
    p = map.parameters(static_cast<int>(i % static_cast<size_t>(S)), static_cast<int>(i / static_cast<size_t>(S)));
    if (rgb) {
      for (int k = 0; k < 18; ++k) a[k] = kCodes * p[static_cast<size_t>(k)];
    } else {
      // colour = L' rgb / 255 with the brightest channel of rgb at 255: L' = L max(chroma).
      const double m = std::max({p[6], p[7], p[8], 1e-12});
      for (int k = 0; k < 6; ++k) a[k] = kCodes * p[static_cast<size_t>(k)] * m;
      for (int c = 0; c < 3; ++c) colour[c] = to_byte(kCodes * std::max(0.0, p[6 + c]) / m);
    }
  };
  const size_t n = static_cast<size_t>(S) * T;
  const int terms = rgb ? 18 : 6;
  Range range[6];
  for (size_t i = 0; i < n; ++i) {
    texel(i);
    for (int j = 0; j < terms; ++j) range[j % 6].add(a[j]);
  }
  double scale[6];
  int bias[6];
  for (int k = 0; k < 6; ++k) {
    scale[k] = range[k].span() / 255.0;
    bias[k] = static_cast<int>(std::clamp(std::lround(-range[k].lo / scale[k]), 0L, 255L));
  }
  std::string bytes = std::string("PTM_1.2\n") + (rgb ? "PTM_FORMAT_RGB\n" : "PTM_FORMAT_LRGB\n") + std::to_string(S) +
                      "\n" + std::to_string(T) + "\n";
  for (int k = 0; k < 6; ++k) bytes += format_float(scale[k]) + (k < 5 ? " " : "\n");
  for (int k = 0; k < 6; ++k) bytes += std::to_string(bias[k]) + (k < 5 ? " " : "\n");
  const size_t header = bytes.size();
  bytes.resize(header + n * (rgb ? 18 : 9));
  char* data = bytes.data() + header;
  // Texel row 0 (smallest y) is the image's bottom row, which PTM stores first.
  for (size_t i = 0; i < n; ++i) {
    texel(i);
    if (rgb) {
      for (int c = 0; c < 3; ++c)  // all red coefficients, then green, then blue
        for (int k = 0; k < 6; ++k)
          data[c * n * 6 + 6 * i + k] = static_cast<char>(to_byte(a[6 * c + k] / scale[k] + bias[k]));
    } else {
      for (int k = 0; k < 6; ++k) data[6 * i + k] = static_cast<char>(to_byte(a[k] / scale[k] + bias[k]));
      for (int c = 0; c < 3; ++c) data[6 * n + 3 * i + c] = static_cast<char>(colour[c]);
    }
  }
  return write_file_atomic(out, bytes);
}

/// The map's HSH coefficients in RTIViewer's basis, K x 3 per texel (a kHsh model's parameters are its bands^2
/// coefficients per colour, colour by colour: ModelBasis).
TexelCoefficients rti_hsh_coefficients(const ParameterMap& map, int bands) {
  const Eigen::MatrixXd convert = vdrig_to_rti_hsh(bands);
  return [&map, convert, bands](int s, int t) {
    const std::vector<double> p = map.parameters(s, t);
    return Eigen::MatrixXd(convert * Eigen::Map<const Eigen::MatrixXd>(p.data(), bands * bands, 3));
  };
}

Status write_rti(const ParameterMap& map, int bands, const fs::path& out) {
  const int S = map.texels_s(), T = map.texels_t(), K = bands * bands;
  const TexelCoefficients coefficients = rti_hsh_coefficients(map, bands);
  // The coefficients are computed twice (the ranges, then the bytes) rather than kept: a matrix per texel was 16 MB
  // at 256 x 256.
  std::vector<Range> range(static_cast<size_t>(K));
  for (int t = 0; t < T; ++t)
    for (int s = 0; s < S; ++s) {
      const Eigen::MatrixXd c = coefficients(s, t);
      for (int k = 0; k < K; ++k)
        for (int ch = 0; ch < 3; ++ch) range[k].add(c(k, ch));
    }
  std::vector<float> scale(static_cast<size_t>(K)), bias(static_cast<size_t>(K));
  for (int k = 0; k < K; ++k) {
    scale[k] = static_cast<float>(range[k].span());
    bias[k] = static_cast<float>(range[k].lo);
  }
  std::string bytes =
      "#HSH1.2\n3\n" + std::to_string(S) + " " + std::to_string(T) + " 3\n" + std::to_string(K) + " 2 1\n";
  static_assert(std::endian::native == std::endian::little, "the .rti floats are little-endian");
  bytes.append(reinterpret_cast<const char*>(scale.data()), 4 * scale.size());
  bytes.append(reinterpret_cast<const char*>(bias.data()), 4 * bias.size());
  bytes.reserve(bytes.size() + static_cast<size_t>(S) * T * 3 * K);
  // Rows top to bottom (file row j is image row j, texel row T - 1 - j), as RTIViewer's loader and relight read
  // them: unlike PTM, whose rows go bottom to top. Per texel the R terms, then G, then B.
  for (int row = 0; row < T; ++row)
    for (int s = 0; s < S; ++s) {
      const Eigen::MatrixXd c = coefficients(s, T - 1 - row);
      for (int ch = 0; ch < 3; ++ch)
        for (int k = 0; k < K; ++k)
          bytes.push_back(static_cast<char>(to_byte((c(k, ch) - bias[k]) / scale[k] * 255.0)));
    }
  return write_file_atomic(out, bytes);
}

Status write_relight(const ParameterMap& map, const fs::path& out, const ExportOptions& options) {
  const int S = map.texels_s(), T = map.texels_t();
  TexelCoefficients coefficients;
  int K = 0;
  std::string type;
  const fitting::ModelBasis basis = map.model().coefficient_basis();
  if (basis.kind == fitting::ModelBasis::Kind::kPtmRgb) {
    K = 6;
    type = "ptm";
    // relight's and OpenLIME's PTM weights are 1, x, y, x^2, xy, y^2 (Rti::lightWeightsPtm, PTM.lightWeights);
    // vdrig's (and the .ptm file's) coefficients are a0 x^2, a1 y^2, a2 xy, a3 x, a4 y, a5.
    coefficients = [&map](int s, int t) {
      const std::vector<double> p = map.parameters(s, t);
      const Eigen::Map<const Eigen::MatrixXd> ours(p.data(), 6, 3);
      Eigen::MatrixXd theirs(6, 3);
      for (int k = 0; k < 6; ++k) theirs.row(k) = ours.row(kRelightPtmOrder[k]);
      return theirs;
    };
  } else if (basis.kind == fitting::ModelBasis::Kind::kHsh && (basis.bands == 2 || basis.bands == 3)) {
    K = basis.bands * basis.bands;
    type = "hsh";
    coefficients = rti_hsh_coefficients(map, basis.bands);
  } else {
    return make_error(ErrorCode::kInvalidArgument,
                      "relight export needs a ptm:rgb, hsh:2 or hsh:3 map, not " + map.model().name());
  }
  // Planes p = 3 k + c: coefficient k of channel c; plane_<k>.jpg holds k's R, G, B.
  std::vector<cv::Mat> planes(static_cast<size_t>(3 * K));
  for (auto& p : planes) p = cv::Mat(T, S, CV_64FC1);
  for (int t = 0; t < T; ++t)
    for (int s = 0; s < S; ++s) {
      const Eigen::MatrixXd c = coefficients(s, t);
      for (int k = 0; k < K; ++k)
        for (int ch = 0; ch < 3; ++ch) planes[static_cast<size_t>(3 * k + ch)].at<double>(T - 1 - t, s) = c(k, ch);
    }
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return make_error(ErrorCode::kIo, "creating " + out.string() + ": " + ec.message());
  nlohmann::json scale = nlohmann::json::array(), bias = nlohmann::json::array();
  for (int k = 0; k < K; ++k) {
    cv::Mat bgr(T, S, CV_8UC3);
    for (int ch = 0; ch < 3; ++ch) {
      double lo, hi;
      cv::minMaxLoc(planes[static_cast<size_t>(3 * k + ch)], &lo, &hi);
      const double span = hi - lo > 1e-12 ? hi - lo : 1e-12;
      scale.push_back(span);
      bias.push_back(-lo / span);
      for (int y = 0; y < T; ++y)
        for (int x = 0; x < S; ++x)
          bgr.at<cv::Vec3b>(y, x)[2 - ch] =
              to_byte((planes[static_cast<size_t>(3 * k + ch)].at<double>(y, x) - lo) / span * 255.0);
    }
    auto jpeg = encode_jpeg_444(bgr, options.jpeg_quality);
    if (!jpeg) return jpeg.error();
    VDRIG_TRY(write_file_atomic(out / ("plane_" + std::to_string(k) + ".jpg"), jpeg.value()));
  }
  // scale and bias belong to the first (only) material: OpenLIME's ShaderRTI.init, relight's Rti::load and
  // relight-core.js all read materials[0].scale/bias.
  const nlohmann::json material = {{"scale", scale}, {"bias", bias}};
  const nlohmann::json info = {{"width", S},
                               {"height", T},
                               {"format", "jpg"},
                               {"type", type},
                               {"colorspace", "rgb"},
                               {"nplanes", 3 * K},
                               {"materials", nlohmann::json::array({material})},
                               {"quality", options.jpeg_quality},
                               {"producer", "vdrig"}};
  return write_file_atomic(out / "info.json", info.dump(1) + "\n");
}

}  // namespace

Result<ExportFormat> parse_export_format(const std::string& text) {
  if (text == "ptm") return ExportFormat::kPtm;
  if (text == "rti") return ExportFormat::kRti;
  if (text == "relight") return ExportFormat::kRelight;
  return make_error(ErrorCode::kInvalidArgument, "format \"" + text + "\": expected ptm, rti or relight");
}

void rti_hsh_basis(int terms, const Vec3d& v, double* w) {
  VDRIG_CHECK(terms == 4 || terms == 9, "rti_hsh_basis: 4 or 9 terms");
  const double pi = std::numbers::pi;
  const double z = std::clamp(v.z(), 0.0, 1.0);
  const double phi = std::atan2(v.y(), v.x());
  const double root = std::sqrt(std::max(0.0, z - z * z));
  w[0] = 1.0 / std::sqrt(2.0 * pi);
  w[1] = std::sqrt(6.0 / pi) * std::cos(phi) * root;
  w[2] = std::sqrt(3.0 / (2.0 * pi)) * (-1.0 + 2.0 * z);
  w[3] = std::sqrt(6.0 / pi) * root * std::sin(phi);
  if (terms == 4) return;
  w[4] = std::sqrt(30.0 / pi) * std::cos(2.0 * phi) * (-z + z * z);
  w[5] = std::sqrt(30.0 / pi) * std::cos(phi) * (-1.0 + 2.0 * z) * root;
  w[6] = std::sqrt(5.0 / (2.0 * pi)) * (1.0 - 6.0 * z + 6.0 * z * z);
  w[7] = std::sqrt(30.0 / pi) * (-1.0 + 2.0 * z) * root * std::sin(phi);
  w[8] = std::sqrt(30.0 / pi) * (-z + z * z) * std::sin(2.0 * phi);
}

Eigen::MatrixXd vdrig_to_rti_hsh(int bands) {
  VDRIG_CHECK(bands == 2 || bands == 3, "vdrig_to_rti_hsh: 2 or 3 bands");
  const int K = bands * bands;
  // Both bases span the same functions (the shifted Legendre polynomials times cos/sin(m phi)); the change of
  // basis is found by least squares on well-spread directions, exact up to rounding.
  std::vector<Vec3d> dirs;
  const int M = 400;
  for (int i = 0; i < M; ++i) {
    const double z = (i + 0.5) / M, r = std::sqrt(1 - z * z), phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
    dirs.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  const Eigen::MatrixXd ours = fitting::hsh_basis_matrix(bands, dirs);
  Eigen::MatrixXd theirs(M, K);
  for (int i = 0; i < M; ++i) {
    double w[9];
    rti_hsh_basis(K, dirs[static_cast<size_t>(i)], w);
    for (int k = 0; k < K; ++k) theirs(i, k) = w[k];
  }
  const Eigen::MatrixXd convert = theirs.colPivHouseholderQr().solve(ours);
  VDRIG_CHECK((theirs * convert - ours).norm() < 1e-9 * ours.norm(), "RTIViewer's HSH basis differs from vdrig's");
  return convert;
}

Status export_map(const ParameterMap& map, ExportFormat format, const fs::path& out, const ExportOptions& options) {
  if (options.jpeg_quality < 1 || options.jpeg_quality > 100)
    return make_error(ErrorCode::kInvalidArgument, "JPEG quality must be 1..100");
  // The formats are defined by their bases: the model says which basis its parameters are in (ModelBasis).
  const fitting::ModelBasis basis = map.model().coefficient_basis();
  using Kind = fitting::ModelBasis::Kind;
  Status status = Status::ok();
  switch (format) {
    case ExportFormat::kPtm:
      if (basis.kind != Kind::kPtmRgb && basis.kind != Kind::kPtmLrgb)
        return make_error(ErrorCode::kInvalidArgument,
                          ".ptm needs a ptm:rgb or ptm:lrgb map, not " + map.model().name());
      status = write_ptm(map, basis.kind == Kind::kPtmRgb, out);
      break;
    case ExportFormat::kRti:
      if (basis.kind != Kind::kHsh || (basis.bands != 2 && basis.bands != 3))
        return make_error(ErrorCode::kInvalidArgument, ".rti needs an hsh:2 or hsh:3 map, not " + map.model().name());
      status = write_rti(map, basis.bands, out);
      break;
    case ExportFormat::kRelight:
      status = write_relight(map, out, options);
      break;
  }
  if (status) log::get("rti")->info("wrote {} ({})", out.string(), map.model().name());
  return status;
}

}  // namespace vdrig::rti

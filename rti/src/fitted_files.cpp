#include "vdrig/rti/fitted_files.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cctype>
#include <cstring>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "relight_layout.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/model.hpp"
#include "vdrig/rti/export.hpp"
#include "vdrig/rti/pca_basis.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;
using fitting::ParameterMap;

constexpr int kMaxSide = 16384;
constexpr size_t kMaxFileBytes = size_t{4} << 30;

Error corrupt(const fs::path& path, const std::string& what) {
  return make_error(ErrorCode::kCorrupt, path.string() + ": " + what);
}

/// Whitespace-separated header tokens of the text at the start of a binary file.
class HeaderReader {
 public:
  explicit HeaderReader(const std::string& bytes) : bytes_(bytes) {}

  bool token(std::string* out) {
    while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    const size_t start = pos_;
    while (pos_ < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    *out = bytes_.substr(start, pos_ - start);
    return pos_ > start;
  }
  bool integer(long* out) {
    std::string t;
    if (!token(&t)) return false;
    char* end = nullptr;
    *out = std::strtol(t.c_str(), &end, 10);
    return *end == '\0';
  }
  bool real(double* out) {
    std::string t;
    if (!token(&t)) return false;
    char* end = nullptr;
    *out = std::strtod(t.c_str(), &end);
    return *end == '\0' && std::isfinite(*out);
  }
  /// Skips comment lines ('#' to the end of the line) and blank space before the next token.
  void skip_comments() {
    for (;;) {
      while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
      if (pos_ >= bytes_.size() || bytes_[pos_] != '#') return;
      while (pos_ < bytes_.size() && bytes_[pos_] != '\n') ++pos_;
    }
  }
  /// The payload starts after the line break that ends the last header token ("\n" or "\r\n").
  size_t payload_start() {
    if (pos_ < bytes_.size() && bytes_[pos_] == '\r') ++pos_;
    if (pos_ < bytes_.size() && bytes_[pos_] == '\n') ++pos_;
    return pos_;
  }

 private:
  const std::string& bytes_;
  size_t pos_ = 0;
};

Status check_size(const fs::path& path, long w, long h) {
  if (w < 1 || h < 1 || w > kMaxSide || h > kMaxSide)
    return make_error(ErrorCode::kInvalidArgument, path.string() + ": size " + std::to_string(w) + "x" +
                                                       std::to_string(h) + " (1.." + std::to_string(kMaxSide) + ")");
  return Status::ok();
}

ParameterMap empty_map(const std::string& model, int w, int h) {
  return ParameterMap(fitting::parse_model(model).value(), w, h, w, h);
}

Result<ParameterMap> read_ptm(const fs::path& path) {
  auto bytes = read_regular_file(path, kMaxFileBytes);
  if (!bytes) return bytes.error();
  HeaderReader in(bytes.value());
  std::string version, format;
  if (!in.token(&version) || version.rfind("PTM_1.", 0) != 0)
    return corrupt(path, "not a PTM file (first line \"" + version.substr(0, 20) + "\", expected PTM_1.2)");
  if (!in.token(&format)) return corrupt(path, "no format line");
  const bool rgb = format == "PTM_FORMAT_RGB", lrgb = format == "PTM_FORMAT_LRGB";
  if (!rgb && !lrgb)
    return make_error(ErrorCode::kUnsupported, path.string() + ": " + format +
                                                   " (vdrig reads PTM_FORMAT_RGB and PTM_FORMAT_LRGB, uncompressed)");
  long w = 0, h = 0;
  if (!in.integer(&w) || !in.integer(&h)) return corrupt(path, "width and height must be integers");
  VDRIG_TRY(check_size(path, w, h));
  double scale[6], bias[6];
  for (double& s : scale)
    if (!in.real(&s)) return corrupt(path, "expected 6 scale values");
  for (double& b : bias)
    if (!in.real(&b)) return corrupt(path, "expected 6 bias values");
  const size_t start = in.payload_start();
  const size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
  const size_t expected = n * (rgb ? 18 : 9);
  if (bytes->size() - start < expected)
    return corrupt(path, "truncated: " + std::to_string(bytes->size() - start) + " payload bytes, " + format + " " +
                             std::to_string(w) + "x" + std::to_string(h) + " needs " + std::to_string(expected));
  const auto* data = reinterpret_cast<const uint8_t*>(bytes->data() + start);
  ParameterMap map = empty_map(rgb ? "ptm:rgb" : "ptm:lrgb", static_cast<int>(w), static_cast<int>(h));
  std::vector<double> p(rgb ? 18 : 9);
  // a_k = (byte - bias_k) scale_k in codes; rows bottom to top, so pixel i is texel (i % w, i / w).
  for (size_t i = 0; i < n; ++i) {
    if (rgb) {
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 6; ++k) p[6 * c + k] = (data[c * n * 6 + 6 * i + k] - bias[k]) * scale[k] / 255.0;
    } else {
      // The viewer shows L(lu, lv) rgb / 255 in codes: L in [0, 1] units times chroma = rgb / 255.
      for (int k = 0; k < 6; ++k) p[k] = (data[6 * i + k] - bias[k]) * scale[k] / 255.0;
      for (int c = 0; c < 3; ++c) p[6 + c] = data[6 * n + 3 * i + c] / 255.0;
    }
    map.set_parameters(static_cast<int>(i % w), static_cast<int>(i / w), p);
  }
  return map;
}

Result<ParameterMap> read_rti(const fs::path& path) {
  auto bytes = read_regular_file(path, kMaxFileBytes);
  if (!bytes) return bytes.error();
  if (bytes->rfind("#HSH1.2", 0) != 0) return corrupt(path, "not an RTIViewer .rti file (no #HSH1.2 line)");
  HeaderReader in(bytes.value());
  in.skip_comments();
  long type = 0, w = 0, h = 0, channels = 0, terms = 0, basis_type = 0, element_bytes = 0;
  if (!in.integer(&type)) return corrupt(path, "expected the file type (3 for HSH)");
  if (type != 3)
    return make_error(ErrorCode::kUnsupported,
                      path.string() + ": .rti file type " + std::to_string(type) + " (vdrig reads type 3, HSH)");
  if (!in.integer(&w) || !in.integer(&h) || !in.integer(&channels))
    return corrupt(path, "expected width, height and colour channels");
  VDRIG_TRY(check_size(path, w, h));
  if (channels != 3) return corrupt(path, std::to_string(channels) + " colour channels (3 expected)");
  if (!in.integer(&terms) || !in.integer(&basis_type) || !in.integer(&element_bytes))
    return corrupt(path, "expected terms, basis type and bytes per element");
  if (terms != 4 && terms != 9)
    return make_error(ErrorCode::kUnsupported,
                      path.string() + ": " + std::to_string(terms) + " HSH terms (vdrig reads 4 and 9)");
  if (element_bytes != 1) return corrupt(path, std::to_string(element_bytes) + " bytes per element (1 expected)");
  const size_t start = in.payload_start();
  const size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
  const size_t expected = 8 * static_cast<size_t>(terms) + n * 3 * static_cast<size_t>(terms);
  if (bytes->size() - start < expected)
    return corrupt(path, "truncated: " + std::to_string(bytes->size() - start) + " bytes after the header, " +
                             std::to_string(expected) + " needed");
  const int K = static_cast<int>(terms), bands = K == 4 ? 2 : 3;
  std::vector<float> scale(static_cast<size_t>(K)), bias(static_cast<size_t>(K));
  std::memcpy(scale.data(), bytes->data() + start, 4 * scale.size());  // little-endian float32, as written
  std::memcpy(bias.data(), bytes->data() + start + 4 * scale.size(), 4 * bias.size());
  const auto* data = reinterpret_cast<const uint8_t*>(bytes->data() + start + 8 * static_cast<size_t>(K));
  const Eigen::MatrixXd to_vdrig = vdrig_to_rti_hsh(bands).inverse();
  ParameterMap map = empty_map("hsh:" + std::to_string(bands), static_cast<int>(w), static_cast<int>(h));
  Eigen::MatrixXd theirs(K, 3);
  for (size_t i = 0; i < n; ++i) {  // rows top to bottom: file row j is texel row h - 1 - j
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < K; ++k) theirs(k, c) = data[(3 * i + c) * K + k] / 255.0 * scale[k] + bias[k];
    const Eigen::MatrixXd ours = to_vdrig * theirs;  // coefficients per colour, colour by colour
    map.set_parameters(static_cast<int>(i % w), static_cast<int>(h - 1 - static_cast<long>(i / w)),
                       std::span<const double>(ours.data(), static_cast<size_t>(ours.size())));
  }
  return map;
}

Result<ParameterMap> read_relight(const fs::path& info_path, const std::string& rbf_model) {
  auto json = read_json_file(info_path);
  if (!json) return json.error();
  const nlohmann::json& info = json.value();
  if (info.contains("type") && info["type"] == "rbf") {  // relight's default basis: refitted (pca_basis.hpp)
    auto model = fitting::parse_model(rbf_model);
    if (!model) return model.error();
    auto basis = read_relight_rbf(info_path);
    if (!basis) return basis.error();
    return rbf_parameter_map(basis.value(), model.value());
  }
  const fs::path dir = info_path.parent_path();
  const auto text = [&](const char* key) {
    return info.contains(key) && info[key].is_string() ? info[key].get<std::string>() : std::string();
  };
  const std::string type = text("type"), colorspace = text("colorspace");
  if ((type != "ptm" && type != "hsh") || colorspace != "rgb")
    return make_error(ErrorCode::kUnsupported,
                      info_path.string() + ": relight basis \"" + type + "\" in colour space \"" + colorspace +
                          "\" (vdrig reads ptm and hsh in rgb, rbf in mrgb; bilinear bases are not read yet)");
  if (!info.contains("width") || !info["width"].is_number_integer() || !info.contains("height") ||
      !info["height"].is_number_integer() || !info.contains("nplanes") || !info["nplanes"].is_number_integer())
    return corrupt(info_path, "width, height and nplanes must be integers");
  const long w = info["width"].get<long>(), h = info["height"].get<long>();
  VDRIG_TRY(check_size(info_path, w, h));
  const int nplanes = info["nplanes"].get<int>();
  const int K = nplanes / 3;
  if (nplanes % 3 != 0 || (type == "ptm" && K != 6) || (type == "hsh" && K != 4 && K != 9))
    return make_error(ErrorCode::kUnsupported, info_path.string() + ": " + std::to_string(nplanes) + " planes of " +
                                                   type + " (vdrig reads ptm 18, hsh 12 or 27)");
  // scale and bias are the first material's (OpenLIME and relight read nothing else); vdrig before 2026-12 wrote
  // them at the top level, which no viewer reads: accepted, with a warning.
  const nlohmann::json* material = nullptr;
  if (info.contains("materials") && info["materials"].is_array() && !info["materials"].empty())
    material = &info["materials"][0];
  else if (info.contains("scale")) {
    log::get("rti")->warn("{}: scale and bias at the top level (an old vdrig export; viewers need materials[0])",
                          info_path.string());
    material = &info;
  }
  if (!material || !material->contains("scale") || !material->contains("bias") || !(*material)["scale"].is_array() ||
      !(*material)["bias"].is_array() || (*material)["scale"].size() < static_cast<size_t>(nplanes) ||
      (*material)["bias"].size() < static_cast<size_t>(nplanes))
    return corrupt(info_path, "materials[0] must hold " + std::to_string(nplanes) + " scale and bias values");
  std::vector<double> scale(static_cast<size_t>(nplanes)), bias(static_cast<size_t>(nplanes));
  for (int p = 0; p < nplanes; ++p) {
    const auto& s = (*material)["scale"][static_cast<size_t>(p)];
    const auto& b = (*material)["bias"][static_cast<size_t>(p)];
    if (!s.is_number() || !b.is_number()) return corrupt(info_path, "scale and bias must be numbers");
    scale[static_cast<size_t>(p)] = s.get<double>();
    bias[static_cast<size_t>(p)] = b.get<double>();
  }
  // Plane p = 3 k + c holds term k of channel c: plane_<k>.jpg carries term k's R, G, B.
  std::vector<cv::Mat> jpegs(static_cast<size_t>(K));
  for (int k = 0; k < K; ++k) {
    const fs::path file = dir / ("plane_" + std::to_string(k) + ".jpg");
    auto image = read_png(file);  // PNG or JPEG
    if (!image) return image.error();
    if (image->cols != w || image->rows != h || image->type() != CV_8UC3)
      return corrupt(file, "a " + std::to_string(image->cols) + "x" + std::to_string(image->rows) + " image with " +
                               std::to_string(image->channels()) + " channels; info.json says " + std::to_string(w) +
                               "x" + std::to_string(h) + " RGB");
    jpegs[static_cast<size_t>(k)] = image.value();
  }
  const int bands = K == 4 ? 2 : 3;
  const Eigen::MatrixXd to_vdrig = type == "hsh" ? vdrig_to_rti_hsh(bands).inverse() : Eigen::MatrixXd();
  ParameterMap map =
      empty_map(type == "ptm" ? "ptm:rgb" : "hsh:" + std::to_string(bands), static_cast<int>(w), static_cast<int>(h));
  Eigen::MatrixXd theirs(K, 3), ours(K, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      for (int k = 0; k < K; ++k) {
        const cv::Vec3b bgr = jpegs[static_cast<size_t>(k)].at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) {
          const size_t p = static_cast<size_t>(3 * k + c);
          theirs(k, c) = (bgr[2 - c] / 255.0 - bias[p]) * scale[p];
        }
      }
      if (type == "ptm")
        for (int k = 0; k < 6; ++k) ours.row(kRelightPtmOrder[k]) = theirs.row(k);
      else
        ours = to_vdrig * theirs;
      map.set_parameters(x, static_cast<int>(h - 1 - y), std::span<const double>(ours.data(), ours.size()));
    }
  return map;
}

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

bool is_fitted_file(const fs::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".ptm" || ext == ".rti" || path.filename() == "info.json") return true;
  std::error_code ec;
  return fs::is_directory(path, ec) && fs::exists(path / "info.json", ec);
}

Result<ParameterMap> read_fitted_file(const fs::path& path, const std::string& rbf_model) {
  const std::string ext = lower_extension(path);
  Result<ParameterMap> map = make_error(ErrorCode::kInternal, "unread");
  if (ext == ".ptm")
    map = read_ptm(path);
  else if (ext == ".rti")
    map = read_rti(path);
  else if (path.filename() == "info.json")
    map = read_relight(path, rbf_model);
  else if (std::error_code ec; fs::is_directory(path, ec))
    map = read_relight(path / "info.json", rbf_model);
  else
    return make_error(ErrorCode::kInvalidArgument,
                      path.string() + ": not a fitted RTI file (.ptm, .rti, or a relight folder with info.json)");
  if (map)
    log::get("rti")->info("read {} ({}, {}x{})", path.string(), map->model().name(), map->texels_s(), map->texels_t());
  return map;
}

}  // namespace vdrig::rti

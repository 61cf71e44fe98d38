// The RTI writers, each checked by a reader written here from the format descriptions (docs/rti.md), not by the
// writer's code: the synthetic stack (synthetic_stack.hpp) is imported, fitted, exported, read back, and the
// radiance reconstructed from the quantised file is compared with the unquantised fit.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <tuple>

#include "fit_support.hpp"
#include "synthetic_stack.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/rti/export.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Splits off `lines` newline-terminated header lines; returns the offset of the payload.
size_t header_lines(const std::string& bytes, int lines, std::vector<std::string>* out) {
  size_t at = 0;
  for (int i = 0; i < lines; ++i) {
    const size_t nl = bytes.find('\n', at);
    out->push_back(bytes.substr(at, nl - at));
    at = nl + 1;
  }
  return at;
}

// RTIViewer's HSH weights, written out from its hweights formulas (theta: zenith, phi: azimuth).
std::vector<double> rtiviewer_hsh(int terms, const Vec3d& l) {
  const double ct = l.z(), phi = std::atan2(l.y(), l.x()), pi = std::numbers::pi;
  const double r = std::sqrt(ct - ct * ct);
  std::vector<double> w = {1 / std::sqrt(2 * pi), std::sqrt(6 / pi) * std::cos(phi) * r,
                           std::sqrt(3 / (2 * pi)) * (-1 + 2 * ct), std::sqrt(6 / pi) * r * std::sin(phi)};
  if (terms == 9) {
    w.push_back(std::sqrt(30 / pi) * std::cos(2 * phi) * (-ct + ct * ct));
    w.push_back(std::sqrt(30 / pi) * std::cos(phi) * (-1 + 2 * ct) * r);
    w.push_back(std::sqrt(5 / (2 * pi)) * (1 - 6 * ct + 6 * ct * ct));
    w.push_back(std::sqrt(30 / pi) * (-1 + 2 * ct) * r * std::sin(phi));
    w.push_back(std::sqrt(30 / pi) * (-ct + ct * ct) * std::sin(2 * phi));
  }
  return w;
}

/// The scale and bias lines of a PTM header.
void ptm_scale_bias(const std::vector<std::string>& header, double scale[6], int bias[6]) {
  std::istringstream s(header[4]), b(header[5]);
  for (int k = 0; k < 6; ++k) s >> scale[k];
  for (int k = 0; k < 6; ++k) b >> bias[k];
}

std::vector<double> ptm_terms(const Vec3d& l) {
  return {l.x() * l.x(), l.y() * l.y(), l.x() * l.y(), l.x(), l.y(), 1.0};
}

class RtiExport : public ::testing::Test {
 protected:
  static constexpr int kS = 20, kT = 14, kLights = 36;

  void SetUp() override {
    stack_ = test::write_synthetic_stack(dir_.path(), kS, kT, kLights);
    ImportOptions o;
    o.linearisation.kind = Linearisation::Kind::kCodes;
    auto imported = import_stack(dir_.path(), dir_ / "map.vdobs", o);
    ASSERT_TRUE(imported) << imported.error().describe();
  }

  fitting::ParameterMap fit(const std::string& model) { return test::fit_imported_stack(dir_ / "map.vdobs", model); }

  /// Compares the reconstruction from a file (`file_code(s, t, l, bound)` in 8-bit codes, with its quantisation
  /// bound) with the unquantised fit, over every texel and every light plus a few off-grid directions.
  template <typename FileCode>
  void expect_within_quantisation(const fitting::ParameterMap& map, FileCode file_code, double max_code_error) {
    std::vector<Vec3d> dirs = stack_.lights;
    dirs.push_back(Vec3d(0, 0, 1));
    dirs.push_back(Vec3d(0.5, -0.5, 0.7).normalized());
    double sq = 0, worst = 0;
    int n = 0;
    for (int t = 0; t < kT; ++t)
      for (int s = 0; s < kS; ++s) {
        const std::vector<double> p = map.parameters(s, t);
        for (const Vec3d& l : dirs) {
          double bound = 0;
          const Vec3d got = file_code(s, t, l, &bound);
          const Vec3d want = 255.0 * map.model().evaluate(p, l);
          for (int c = 0; c < 3; ++c) {
            const double e = std::abs(got[c] - want[c]);
            ASSERT_LE(e, bound + 1e-6) << "texel " << s << "," << t << " channel " << c;
            sq += e * e;
            worst = std::max(worst, e);
            ++n;
          }
        }
      }
    EXPECT_LE(worst, max_code_error);
    EXPECT_LT(std::sqrt(sq / n), 0.5);
  }

  test::TempDir dir_{"rti_export"};
  test::SyntheticStack stack_;
};

TEST_F(RtiExport, PtmRgbReadBackByTheFormatDescription) {
  const fitting::ParameterMap map = fit("ptm:rgb");
  ASSERT_TRUE(export_map(map, ExportFormat::kPtm, dir_ / "out.ptm"));
  const std::string bytes = slurp(dir_ / "out.ptm");
  std::vector<std::string> h;
  const size_t at = header_lines(bytes, 6, &h);
  ASSERT_EQ(h[0], "PTM_1.2");
  ASSERT_EQ(h[1], "PTM_FORMAT_RGB");
  ASSERT_EQ(std::stoi(h[2]), kS);
  ASSERT_EQ(std::stoi(h[3]), kT);
  double scale[6];
  int bias[6];
  ptm_scale_bias(h, scale, bias);
  const size_t n = static_cast<size_t>(kS) * kT;
  ASSERT_EQ(bytes.size() - at, 18 * n);  // 3 colour blocks of 6 bytes per pixel
  const auto* data = reinterpret_cast<const uint8_t*>(bytes.data() + at);
  expect_within_quantisation(
      map,
      [&](int s, int t, const Vec3d& l, double* bound) {
        const std::vector<double> b = ptm_terms(l);
        const size_t pixel = static_cast<size_t>(t) * kS + s;  // rows bottom to top
        Vec3d code = Vec3d::Zero();
        *bound = 0;
        for (int c = 0; c < 3; ++c)
          for (int k = 0; k < 6; ++k) code[c] += (data[c * n * 6 + pixel * 6 + k] - bias[k]) * scale[k] * b[k];
        for (int k = 0; k < 6; ++k) *bound += scale[k] * std::abs(b[k]);
        return code;
      },
      1.0);
}

TEST_F(RtiExport, PtmLrgbReadBackByTheFormatDescription) {
  const fitting::ParameterMap map = fit("ptm:lrgb");
  ASSERT_TRUE(export_map(map, ExportFormat::kPtm, dir_ / "out.ptm"));
  const std::string bytes = slurp(dir_ / "out.ptm");
  std::vector<std::string> h;
  const size_t at = header_lines(bytes, 6, &h);
  ASSERT_EQ(h[1], "PTM_FORMAT_LRGB");
  double scale[6];
  int bias[6];
  ptm_scale_bias(h, scale, bias);
  const size_t n = static_cast<size_t>(kS) * kT;
  ASSERT_EQ(bytes.size() - at, 9 * n);  // 6 luminance bytes per pixel, then 3 colour bytes per pixel
  const auto* data = reinterpret_cast<const uint8_t*>(bytes.data() + at);
  expect_within_quantisation(
      map,
      [&](int s, int t, const Vec3d& l, double* bound) {
        const std::vector<double> b = ptm_terms(l);
        const size_t pixel = static_cast<size_t>(t) * kS + s;
        double lum = 0, lum_bound = 0;
        for (int k = 0; k < 6; ++k) {
          lum += (data[pixel * 6 + k] - bias[k]) * scale[k] * b[k];
          lum_bound += scale[k] * std::abs(b[k]);
        }
        Vec3d code;
        for (int c = 0; c < 3; ++c) code[c] = lum * data[6 * n + pixel * 3 + c] / 255.0;
        *bound = lum_bound + std::abs(lum) * 0.5 / 255.0;
        return code;
      },
      1.0);
}

TEST_F(RtiExport, RtiHshReadBackByRtiViewersLayout) {
  const fitting::ParameterMap map = fit("hsh:3");
  ASSERT_TRUE(export_map(map, ExportFormat::kRti, dir_ / "out.rti"));
  const std::string bytes = slurp(dir_ / "out.rti");
  std::vector<std::string> h;
  size_t at = header_lines(bytes, 4, &h);
  ASSERT_EQ(h[0], "#HSH1.2");
  ASSERT_EQ(h[1], "3");
  int w = 0, hh = 0, colours = 0, terms = 0, basis = 0, elem = 0;
  std::istringstream(h[2]) >> w >> hh >> colours;
  std::istringstream(h[3]) >> terms >> basis >> elem;
  ASSERT_EQ(w, kS);
  ASSERT_EQ(hh, kT);
  ASSERT_EQ(colours, 3);
  ASSERT_EQ(terms, 9);
  ASSERT_EQ(elem, 1);
  std::vector<float> scale(9), bias(9);
  std::memcpy(scale.data(), bytes.data() + at, 36);
  std::memcpy(bias.data(), bytes.data() + at + 36, 36);
  at += 72;
  ASSERT_EQ(bytes.size() - at, static_cast<size_t>(kS) * kT * 27);
  const auto* data = reinterpret_cast<const uint8_t*>(bytes.data() + at);
  expect_within_quantisation(
      map,
      [&](int s, int t, const Vec3d& l, double* bound) {
        const std::vector<double> wts = rtiviewer_hsh(9, l);
        const size_t pixel = static_cast<size_t>(kT - 1 - t) * kS + s;  // rows top to bottom, as RTIViewer reads
        Vec3d value = Vec3d::Zero();
        *bound = 0;
        for (int c = 0; c < 3; ++c)
          for (int k = 0; k < 9; ++k) value[c] += (data[pixel * 27 + c * 9 + k] / 255.0 * scale[k] + bias[k]) * wts[k];
        for (int k = 0; k < 9; ++k) *bound += 255.0 * scale[k] * (0.5 / 255.0) * std::abs(wts[k]);  // in codes
        return Vec3d(255.0 * value);
      },
      1.0);
}

TEST_F(RtiExport, RelightPlanesReadBackAsOpenLimeDecodesThem) {
  const fitting::ParameterMap map = fit("hsh:3");
  ExportOptions options;
  options.jpeg_quality = 100;
  ASSERT_TRUE(export_map(map, ExportFormat::kRelight, dir_ / "web", options));
  const nlohmann::json info = nlohmann::json::parse(slurp(dir_ / "web" / "info.json"));
  ASSERT_EQ(info["type"], "hsh");
  ASSERT_EQ(info["colorspace"], "rgb");
  ASSERT_EQ(info["nplanes"], 27);
  ASSERT_EQ(info["width"], kS);
  ASSERT_EQ(info["height"], kT);
  std::vector<cv::Mat> jpegs;
  for (int k = 0; k < 9; ++k)
    jpegs.push_back(cv::imread((dir_ / "web" / ("plane_" + std::to_string(k) + ".jpg")).string()));
  ASSERT_FALSE(info.contains("scale"));  // the viewers read materials[0] only
  const std::vector<double> scale = info["materials"][0]["scale"], bias = info["materials"][0]["bias"];
  expect_within_quantisation(
      map,
      [&](int s, int t, const Vec3d& l, double* bound) {
        const std::vector<double> wts = rtiviewer_hsh(9, l);
        Vec3d value = Vec3d::Zero();
        *bound = 0;
        for (int k = 0; k < 9; ++k)
          for (int c = 0; c < 3; ++c) {
            const int p = 3 * k + c;
            const double byte = jpegs[k].at<cv::Vec3b>(kT - 1 - t, s)[2 - c];  // planes top row first
            value[c] += (byte / 255.0 - bias[p]) * scale[p] * wts[k];
            // Rounding plus the JPEG error at quality 100 (4:4:4): a byte within 2 codes.
            *bound += 255.0 * scale[p] * (2.5 / 255.0) * std::abs(wts[k]);  // in codes
          }
        return Vec3d(255.0 * value);
      },
      2.0);
}

TEST_F(RtiExport, WrongModelsAreRefused) {
  const fitting::ParameterMap map = fit("hsh:4");
  auto ptm = export_map(map, ExportFormat::kPtm, dir_ / "x.ptm");
  ASSERT_FALSE(ptm);
  EXPECT_NE(ptm.error().message.find(".ptm needs a ptm:rgb or ptm:lrgb map, not hsh:4"), std::string::npos);
  EXPECT_FALSE(export_map(map, ExportFormat::kRti, dir_ / "x.rti"));
  EXPECT_EQ(parse_export_format("png").error().code, ErrorCode::kInvalidArgument);
}

TEST_F(RtiExport, FitMatchesTheGroundTruthAndLeaveOneOutIsTheRefitResidual) {
  const fitting::ParameterMap map = fit("hsh:3");
  auto obs = fitting::ObsMapReader::open(dir_ / "map.vdobs")->read_all();
  ASSERT_TRUE(obs);
  const int s = 7, t = 5;
  const fitting::TexelObservations texel = obs->texel(s, t);
  // Brute-force LOO: refit without each sample and predict it.
  double sq = 0;
  for (size_t j = 0; j < texel.size(); ++j) {
    std::vector<Vec3d> dirs;
    Eigen::MatrixXd values(static_cast<Eigen::Index>(texel.size() - 1), 3);
    for (size_t i = 0, r = 0; i < texel.size(); ++i)
      if (i != j) {
        dirs.push_back(texel.direction[i].cast<double>());
        values.row(static_cast<Eigen::Index>(r++)) = texel.radiance[i].cast<double>().transpose();
      }
    fitting::HshFitOptions o;
    o.bands = 3;
    const Eigen::MatrixXd c = fitting::fit_hsh(o, dirs, values);
    const double predicted = fitting::eval_hsh(c, texel.direction[j].cast<double>())[0];
    sq += std::pow(predicted - texel.radiance[j][0], 2);
  }
  EXPECT_NEAR(map.at("loo.R", s, t), std::sqrt(sq / static_cast<double>(texel.size())), 1e-5);
  EXPECT_GT(map.at("loo.R", s, t), map.at("rms.R", s, t));
}

TEST_F(RtiExport, FitsMatchTheTrueRadianceBetweenTheLights) {
  // Judged where a viewer looks: at light directions the stack did not photograph (a second spiral, rotated so that
  // none is a stack light), against the stack's true radiance before 8-bit quantisation.
  std::vector<Vec3d> between = test::spiral_lights(60);
  const Eigen::AngleAxisd turn(0.37, Vec3d::UnitZ());
  for (Vec3d& l : between) l = turn * l;
  for (const auto& [model, mean_bound, max_bound] :
       // Measured: hsh:3 mean 0.51, max 10.7 codes (near the horizon, where the spiral's lights thin out); ptm:rgb
       // 3.28 and 13.2 (a biquadratic cannot follow the cosine). Bounds 1.5x.
       {std::tuple{"hsh:3", 0.76, 16.0}, std::tuple{"ptm:rgb", 4.9, 20.0}}) {
    const fitting::ParameterMap map = fit(model);
    double sum = 0, worst = 0;
    int n = 0;
    for (int t = 0; t < kT; ++t)
      for (int s = 0; s < kS; ++s)
        for (const Vec3d& l : between) {
          const Vec3d e = 255.0 * (map.evaluate(s, t, l) - stack_.radiance(s, t, l)).cwiseAbs();
          sum += e.sum();
          worst = std::max(worst, e.maxCoeff());
          n += 3;
        }
    std::printf("%s between the lights: mean %.3f codes, max %.2f codes\n", model, sum / n, worst);
    EXPECT_LT(sum / n, mean_bound) << model;
    EXPECT_LT(worst, max_bound) << model;
  }
}

}  // namespace
}  // namespace vdrig::rti

#include "vdrig/fitting/ptm_model.hpp"

#include <Eigen/Core>
#include <cmath>

#include "linear_texel_fit.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/sh.hpp"  // least_squares_operator, LinearFitOperator

namespace vdrig::fitting {
namespace {

constexpr int kTerms = 6;

Eigen::MatrixXd ptm_basis_matrix(const std::vector<Vec3d>& directions) {
  Eigen::MatrixXd basis(static_cast<Eigen::Index>(directions.size()), kTerms);
  for (size_t j = 0; j < directions.size(); ++j) {
    double b[kTerms];
    ptm_basis(directions[j].normalized(), b);
    for (int i = 0; i < kTerms; ++i) basis(static_cast<Eigen::Index>(j), i) = b[i];
  }
  return basis;
}

Eigen::MatrixXd ptm_operator(const std::vector<Vec3d>& directions) {
  return least_squares_operator(ptm_basis_matrix(directions), {}, Eigen::VectorXd());
}

class PtmTexelFitter : public TexelFitter {
 public:
  explicit PtmTexelFitter(PtmModel::Variant variant) : variant_(variant), fit_(ptm_basis_matrix, ptm_operator) {}

  std::vector<double> fit(const TexelObservations& obs) override {
    const auto n = static_cast<Eigen::Index>(obs.size());
    rgb_.resize(n, 3);
    for (Eigen::Index i = 0; i < n; ++i) rgb_.row(i) = obs.radiance[static_cast<size_t>(i)].cast<double>().transpose();
    if (variant_ == PtmModel::Variant::kRgb) {
      const Eigen::MatrixXd a = fit_.fit(obs, rgb_);  // 6 x 3
      return std::vector<double>(a.data(), a.data() + a.size());
    }
    const Eigen::VectorXd luminance = rgb_.rowwise().mean();
    const Eigen::VectorXd a = fit_.fit(obs, luminance);
    const double sum_y = luminance.sum();
    std::vector<double> p(a.data(), a.data() + kTerms);
    for (int c = 0; c < 3; ++c) p.push_back(sum_y > 0 ? rgb_.col(c).sum() / sum_y : 1.0);
    return p;
  }

  bool quality(const TexelObservations& /*obs*/, std::span<const double> p, FitQuality* q, Vec3d* loo_rms) override {
    if (variant_ == PtmModel::Variant::kRgb) {
      fit_.quality(rgb_, Eigen::Map<const Eigen::MatrixXd>(p.data(), kTerms, 3), q, loo_rms);
      return true;
    }
    // radiance_c = (Y basis a) chroma_c: the luminance fit's predictions and LOO predictions times the chromaticity.
    const Eigen::Map<const Eigen::VectorXd> a(p.data(), kTerms);
    const Eigen::VectorXd y = fit_.basis_matrix() * a;
    const Eigen::VectorXd y_loo = fit_.leave_one_out(rgb_.rowwise().mean(), y);
    const Eigen::RowVector3d chroma(p[kTerms], p[kTerms + 1], p[kTerms + 2]);
    SharedDirectionLinearFit::residual_quality(rgb_, y * chroma, y_loo * chroma, q, loo_rms);
    return true;
  }

 private:
  PtmModel::Variant variant_;
  SharedDirectionLinearFit fit_;
  Eigen::MatrixXd rgb_;  // the last texel's observations, N x 3
};

}  // namespace

void ptm_basis(const Vec3d& v, double out[6]) {
  const double lu = v.x(), lv = v.y();
  out[0] = lu * lu;
  out[1] = lv * lv;
  out[2] = lu * lv;
  out[3] = lu;
  out[4] = lv;
  out[5] = 1.0;
}

std::string PtmModel::name() const { return variant_ == Variant::kRgb ? "ptm:rgb" : "ptm:lrgb"; }

std::vector<std::string> PtmModel::channels() const {
  std::vector<std::string> names;
  if (variant_ == Variant::kRgb) {
    for (const char* c : {"R", "G", "B"})
      for (int i = 0; i < kTerms; ++i) names.push_back(std::string("ptm.") + c + "." + std::to_string(i));
  } else {
    for (int i = 0; i < kTerms; ++i) names.push_back("ptm.L." + std::to_string(i));
    for (const char* c : {"R", "G", "B"}) names.push_back(std::string("chroma.") + c);
  }
  return names;
}

Vec3d PtmModel::evaluate(std::span<const double> p, const Vec3d& v) const {
  VDRIG_CHECK(static_cast<int>(p.size()) == parameter_count(), "PtmModel: wrong parameter count");
  double b[kTerms];
  ptm_basis(v, b);
  Vec3d rgb;
  if (variant_ == Variant::kRgb) {
    for (int c = 0; c < 3; ++c) {
      rgb[c] = 0;
      for (int i = 0; i < kTerms; ++i) rgb[c] += p[static_cast<size_t>(kTerms * c + i)] * b[i];
    }
  } else {
    double y = 0;
    for (int i = 0; i < kTerms; ++i) y += p[static_cast<size_t>(i)] * b[i];
    for (int c = 0; c < 3; ++c) rgb[c] = y * p[static_cast<size_t>(kTerms + c)];
  }
  return rgb;
}

std::string PtmModel::glsl(const std::function<std::string(int parameter)>& parameter) const {
  std::string s = "vec3 model(ivec2 t, vec3 v) {\n";
  s += "  float b[6] = float[6](v.x * v.x, v.y * v.y, v.x * v.y, v.x, v.y, 1.0);\n";
  if (variant_ == Variant::kRgb) {
    s += "  vec3 I = vec3(0.0);\n";
    for (int i = 0; i < kTerms; ++i)
      s += "  I += b[" + std::to_string(i) + "] * vec3(" + parameter(i) + ", " + parameter(kTerms + i) + ", " +
           parameter(2 * kTerms + i) + ");\n";
    s += "  return I;\n}\n";
  } else {
    s += "  float y = 0.0;\n";
    for (int i = 0; i < kTerms; ++i) s += "  y += b[" + std::to_string(i) + "] * " + parameter(i) + ";\n";
    s += "  return y * vec3(" + parameter(kTerms) + ", " + parameter(kTerms + 1) + ", " + parameter(kTerms + 2) +
         ");\n}\n";
  }
  return s;
}

Result<LinearFitOperator> PtmModel::fit_operator(const std::vector<Vec3d>& directions, const MapFitOptions&) const {
  if (variant_ != Variant::kRgb)
    return make_error(ErrorCode::kUnsupported, "ptm:lrgb is not linear in the radiance (chromaticity is a ratio)");
  return LinearFitOperator(ptm_operator(directions));
}

std::vector<double> PtmModel::sample_parameters(unsigned seed) const {
  // The constant term (a5) well above the varying ones, so the radiance stays positive; chromaticities near 1.
  const double phase = 0.9 * static_cast<double>(seed);
  std::vector<double> p(static_cast<size_t>(parameter_count()));
  for (size_t i = 0; i < p.size(); ++i) {
    const bool chroma = variant_ == Variant::kLrgb && i >= static_cast<size_t>(kTerms);
    p[i] = chroma                                       ? 0.8 + 0.1 * static_cast<double>(i % 3)
           : static_cast<int>(i % kTerms) == kTerms - 1 ? 4.0 + 0.1 * static_cast<double>(i)
                                                        : 0.3 * std::sin(1.3 * static_cast<double>(i) + phase);
  }
  return p;
}

ModelBasis PtmModel::coefficient_basis() const {
  return {variant_ == Variant::kRgb ? ModelBasis::Kind::kPtmRgb : ModelBasis::Kind::kPtmLrgb, 0};
}

Result<ParameterMap> PtmModel::fit_map(const MapFitContext& context) const {
  const Variant variant = variant_;
  return fit_map_per_texel(shared_from_this(), context,
                           [variant] { return std::make_unique<PtmTexelFitter>(variant); });
}

void register_ptm_model(ModelRegistry& registry) {
  registry.add({"ptm",
                "ptm:rgb|ptm:lrgb",
                [](const std::string& settings) -> Result<ModelPtr> {
                  if (settings.empty() || settings == "rgb")
                    return ModelPtr(std::make_shared<PtmModel>(PtmModel::Variant::kRgb));
                  if (settings == "lrgb") return ModelPtr(std::make_shared<PtmModel>(PtmModel::Variant::kLrgb));
                  return make_error(ErrorCode::kInvalidArgument, "variant must be rgb or lrgb");
                },
                {"ptm:rgb", "ptm:lrgb"}});
}

}  // namespace vdrig::fitting

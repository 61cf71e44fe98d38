#include "vdrig/fitting/harmonic_model.hpp"

#include <cmath>
#include <cstdio>

#include "linear_texel_fit.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {
namespace {

struct Family {
  const char* name;
  HarmonicModel::Basis basis;
  ShFitMethod method;
};
constexpr Family kFamilies[] = {
    {"sh-zh", HarmonicModel::Basis::kSh, ShFitMethod::kZeroHemisphere},
    {"sh-lsop", HarmonicModel::Basis::kSh, ShFitMethod::kLsop},
    {"sh-ls", HarmonicModel::Basis::kSh, ShFitMethod::kLeastSquares},
    {"hsh", HarmonicModel::Basis::kHsh, ShFitMethod::kLeastSquares},
};

Result<int> parse_bands(const std::string& settings) {
  if (settings.empty() || settings.size() > 2 || settings.find_first_not_of("0123456789") != std::string::npos)
    return make_error(ErrorCode::kInvalidArgument, "not a number");
  const int bands = std::stoi(settings);
  if (bands < 1 || bands > kMaxShBands) return make_error(ErrorCode::kInvalidArgument, "bands must be 1..10");
  return bands;
}

/// A double as a GLSL float literal (enough digits for float precision).
std::string glsl_float(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9e", v);
  return buf;
}

class HarmonicTexelFitter : public TexelFitter {
 public:
  HarmonicTexelFitter(HarmonicModel::Basis basis, const ShFitOptions& sh, const HshFitOptions& hsh)
      : sh_(basis == HarmonicModel::Basis::kSh ? std::make_unique<ShTexelFitter>(sh) : nullptr),
        hsh_(hsh_basis_function(hsh.bands),
             [hsh](const std::vector<Vec3d>& dirs) { return make_hsh_fit_operator(hsh, dirs).matrix(); }) {}

  std::vector<double> fit(const TexelObservations& obs) override {
    values_.resize(static_cast<Eigen::Index>(obs.size()), 3);
    for (size_t i = 0; i < obs.size(); ++i)
      values_.row(static_cast<Eigen::Index>(i)) = obs.radiance[i].cast<double>().transpose();
    Eigen::MatrixXd coeffs;
    if (sh_) {
      std::vector<Vec3d> dirs(obs.size());
      for (size_t i = 0; i < obs.size(); ++i) dirs[i] = obs.direction[i].cast<double>();
      coeffs = sh_->fit(dirs, values_);
    } else {
      coeffs = hsh_.fit(obs, values_);  // one operator for every texel with the same directions
    }
    return std::vector<double>(coeffs.data(), coeffs.data() + coeffs.size());  // column-major: channel by channel
  }

  bool quality(const TexelObservations& /*obs*/, std::span<const double> parameters, FitQuality* q,
               Vec3d* loo_rms) override {
    if (sh_) return false;
    const auto k = static_cast<Eigen::Index>(parameters.size() / 3);
    hsh_.quality(values_, Eigen::Map<const Eigen::MatrixXd>(parameters.data(), k, 3), q, loo_rms);
    return true;
  }

 private:
  static SharedDirectionLinearFit::Basis hsh_basis_function(int bands) {
    return [bands](const std::vector<Vec3d>& dirs) { return hsh_basis_matrix(bands, dirs); };
  }

  std::unique_ptr<ShTexelFitter> sh_;  // holds the Gram factorisation and work space
  SharedDirectionLinearFit hsh_;
  Eigen::MatrixXd values_;  // the last texel's observations, N x 3
};

const HarmonicModel& harmonic_model_of(const ParameterMap& map) {
  const auto* m = dynamic_cast<const HarmonicModel*>(&map.model());
  VDRIG_CHECK(m, "not an SH or HSH map: " + map.model().name());
  return *m;
}

}  // namespace

HarmonicModel::HarmonicModel(Basis basis, ShFitMethod method, int bands)
    : basis_(basis), method_(basis == Basis::kHsh ? ShFitMethod::kLeastSquares : method), bands_(bands) {
  VDRIG_CHECK(bands >= 1 && bands <= kMaxShBands, "HarmonicModel: bands out of range");
}

std::string HarmonicModel::family() const {
  for (const Family& f : kFamilies)
    if (f.basis == basis_ && (basis_ == Basis::kHsh || f.method == method_)) return f.name;
  VDRIG_CHECK(false, "HarmonicModel: no family");
  return "";
}

std::string HarmonicModel::name() const { return family() + ":" + std::to_string(bands_); }

std::vector<std::string> HarmonicModel::channels() const {
  const std::string prefix = basis_ == Basis::kHsh ? "hsh." : "sh.";
  std::vector<std::string> names;
  for (const char* c : {"R", "G", "B"})
    for (int i = 0; i < coefficients_per_channel(); ++i) {
      char idx[16];
      std::snprintf(idx, sizeof idx, "%02d", i);
      names.push_back(prefix + c + "." + idx);
    }
  return names;
}

void HarmonicModel::write_attributes(std::map<std::string, double>& number_attributes) const {
  number_attributes["vdrig.bands"] = bands_;
}

Vec3d HarmonicModel::evaluate(std::span<const double> parameters, const Vec3d& v) const {
  VDRIG_CHECK(static_cast<int>(parameters.size()) == 3 * coefficients_per_channel(),
              "HarmonicModel: wrong parameter count");
  const Eigen::Map<const Eigen::MatrixXd> coeffs(parameters.data(), coefficients_per_channel(), 3);
  return basis_ == Basis::kHsh ? Vec3d(eval_hsh(coeffs, v)) : Vec3d(eval_sh(coeffs, v));
}

// Straight-line code for the n bands: the computation of core's sh_basis with its recurrence constants baked in.
// Per order m, Q_l^m by the normalised recurrence, times sqrt2 (Re, Im)((x + i y)^m) for m != 0. HSH (hsh.hpp)
// evaluate the same at d' = (k x, k y, 2 z - 1), k = 2 sqrt(z / (1 + z)), z clamped to [0, 1], times sqrt2.
std::string HarmonicModel::glsl(const std::function<std::string(int parameter)>& parameter) const {
  const int n = bands_, per_channel = coefficients_per_channel();
  const bool hsh = basis_ == Basis::kHsh;
  auto coeff = [&](int l, int m) {
    const int i = sh_index(l, m);
    return "vec3(" + parameter(i) + ", " + parameter(per_channel + i) + ", " + parameter(2 * per_channel + i) + ")";
  };
  const std::string sqrt2 = glsl_float(std::sqrt(2.0));
  std::string s = "vec3 model(ivec2 t, vec3 v) {\n";
  if (hsh) {
    s += "  float zc = clamp(v.z, 0.0, 1.0);\n  float k = 2.0 * sqrt(zc / (1.0 + zc));\n";
    s += "  float x = k * v.x, y = k * v.y, z = 2.0 * zc - 1.0;\n";
  } else {
    s += "  float x = v.x, y = v.y, z = v.z;\n";
  }
  s += "  vec3 I = vec3(0.0);\n  float re = 1.0, im = 0.0, re_next;\n";
  for (int m = 0; m < n; ++m) {
    s += "  {\n    float q2 = 0.0, q1 = " + glsl_float(sh_recurrence_diag(m)) + ", q = q1;\n";
    for (int l = m; l < n; ++l) {
      if (l > m)
        s += "    q = " + glsl_float(sh_recurrence_a(l, m)) + " * (z * q1 - " + glsl_float(sh_recurrence_b(l, m)) +
             " * q2);\n    q2 = q1;\n    q1 = q;\n";
      if (m == 0)
        s += "    I += q * " + coeff(l, 0) + ";\n";
      else
        s += "    I += " + sqrt2 + " * q * (re * " + coeff(l, m) + " + im * " + coeff(l, -m) + ");\n";
    }
    s += "  }\n  re_next = re * x - im * y;\n  im = re * y + im * x;\n  re = re_next;\n";
  }
  s += hsh ? "  return " + sqrt2 + " * I;\n}\n" : "  return I;\n}\n";
  return s;
}

namespace {

/// The fit options of `model` from the map's: bands (and SH method) from the model name, the rest as given.
struct HarmonicFitOptions {
  ShFitOptions sh;
  HshFitOptions hsh;
};

Result<HarmonicFitOptions> resolve(const HarmonicModel& model, ShFitMethod method, const MapFitOptions& options) {
  HarmonicFitOptions r{options.model_options.get<ShFitOptions>(), options.model_options.get<HshFitOptions>()};
  std::string why;
  if (model.basis() == HarmonicModel::Basis::kHsh) {
    r.hsh.bands = model.bands();
    if (!r.hsh.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else {
    r.sh.bands = model.bands();
    r.sh.method = method;
    if (!r.sh.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  }
  return r;
}

}  // namespace

Result<LinearFitOperator> HarmonicModel::fit_operator(const std::vector<Vec3d>& directions,
                                                      const MapFitOptions& options) const {
  auto r = resolve(*this, method_, options);
  if (!r) return r.error();
  return basis_ == Basis::kHsh ? make_hsh_fit_operator(r->hsh, directions) : make_sh_fit_operator(r->sh, directions);
}

Status HarmonicModel::check_options(const MapFitOptions& options) const {
  VDRIG_TRY(ReflectanceModel::check_options(options));
  auto r = resolve(*this, method_, options);
  if (!r) return r.error();
  return Status::ok();
}

std::string HarmonicModel::options_fingerprint(const MapFitOptions& options) const {
  auto r = resolve(*this, method_, options);
  // Options it refuses fit nothing; their text still differs from every valid one.
  const ShFitOptions sh = r ? r->sh : options.model_options.get<ShFitOptions>();
  const HshFitOptions hsh = r ? r->hsh : options.model_options.get<HshFitOptions>();
  return basis_ == Basis::kHsh ? hsh.fingerprint() : sh.fingerprint();
}

std::vector<double> HarmonicModel::sample_parameters(unsigned seed) const {
  // A constant term (coefficient 0 of each colour) well above the varying ones, which fall off as 1 / (l + 1)^2 so
  // that even ten bands in phase cannot take the radiance to 0.
  const int k = coefficients_per_channel();
  const double phase = 0.9 * static_cast<double>(seed);
  std::vector<double> p(static_cast<size_t>(3 * k));
  for (int ch = 0; ch < 3; ++ch)
    for (int i = 0; i < k; ++i) {
      const double l = std::floor(std::sqrt(static_cast<double>(i)));
      p[static_cast<size_t>(ch * k + i)] =
          i == 0 ? 4.0 + ch + 0.5 * std::sin(phase) : 0.2 / ((l + 1) * (l + 1)) * std::sin(1.3 * i + 0.7 * ch + phase);
    }
  return p;
}

ModelBasis HarmonicModel::coefficient_basis() const {
  return {basis_ == Basis::kHsh ? ModelBasis::Kind::kHsh : ModelBasis::Kind::kSh, bands_};
}

Result<ParameterMap> HarmonicModel::fit_map(const MapFitContext& context) const {
  auto r = resolve(*this, method_, context.options);
  if (!r) return r.error();
  const HarmonicFitOptions options = r.value();
  const Basis basis = basis_;
  return fit_map_per_texel(shared_from_this(), context, [basis, options] {
    return std::make_unique<HarmonicTexelFitter>(basis, options.sh, options.hsh);
  });
}

void register_harmonic_models(ModelRegistry& registry) {
  for (const Family& f : kFamilies) {
    const Family family = f;
    const std::string name = f.name;
    registry.add({name,
                  name + ":N",
                  [family](const std::string& settings) -> Result<ModelPtr> {
                    auto bands = parse_bands(settings);
                    if (!bands) return bands.error();
                    return ModelPtr(std::make_shared<HarmonicModel>(family.basis, family.method, bands.value()));
                  },
                  {name + ":1", name + ":5", name + ":10"}});
  }
}

Eigen::MatrixXd harmonic_coefficients(const ParameterMap& map, int s, int t) {
  const HarmonicModel& model = harmonic_model_of(map);
  const std::vector<double> p = map.parameters(s, t);
  return Eigen::Map<const Eigen::MatrixXd>(p.data(), model.coefficients_per_channel(), 3);
}

void set_harmonic_coefficients(ParameterMap& map, int s, int t, const Eigen::MatrixXd& coefficients) {
  const HarmonicModel& model = harmonic_model_of(map);
  VDRIG_CHECK(coefficients.rows() == model.coefficients_per_channel() && coefficients.cols() == 3,
              "set_harmonic_coefficients: coefficients must be n^2 x 3");
  map.set_parameters(s, t, std::span<const double>(coefficients.data(), static_cast<size_t>(coefficients.size())));
}

}  // namespace vdrig::fitting

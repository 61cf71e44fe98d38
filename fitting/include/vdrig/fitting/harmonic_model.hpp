// Spherical-harmonic reflectance models of a parameter map (sh.hpp and hsh.hpp have the bases and their fits):
// "sh-zh:N", "sh-lsop:N", "sh-ls:N" (real SH fitted by zero-hemisphere projection, least-squares optimal projection
// or least squares) and "hsh:N" (hemispherical harmonics), N = 1..10 bands, N^2 coefficients per colour channel.
//
// Channels: sh.<C>.<ii> (hsh.<C>.<ii> for HSH), C = R, G, B, ii = l (l + 1) + m as two digits, in the order
// R 00..N^2-1, G ..., B ...; a texel's parameters are therefore the N^2 x 3 coefficient matrix in column-major
// order. Header attribute: vdrig.bands. Its map fit honours MapFitOptions::model_options' ShFitOptions (SH) or
// HshFitOptions (HSH), bands and SH method taken from the name; its options_fingerprint is that set.
#pragma once

#include <Eigen/Core>

#include "vdrig/fitting/model.hpp"
#include "vdrig/fitting/sh.hpp"

namespace vdrig::fitting {

class HarmonicModel : public ReflectanceModel {
 public:
  enum class Basis { kSh, kHsh };
  /// bands 1..kMaxShBands; `method` is ignored for HSH.
  HarmonicModel(Basis basis, ShFitMethod method, int bands);

  Basis basis() const { return basis_; }
  int bands() const { return bands_; }
  int coefficients_per_channel() const { return sh_coeff_count(bands_); }

  std::string family() const override;
  std::string name() const override;
  std::vector<std::string> channels() const override;
  void write_attributes(std::map<std::string, double>& number_attributes) const override;
  Vec3d evaluate(std::span<const double> parameters, const Vec3d& v) const override;
  std::string glsl(const std::function<std::string(int parameter)>& parameter) const override;
  bool linear_in_shared_directions() const override { return true; }
  /// HSH maps carry loo.R/G/B (their texels share one least-squares operator per direction set).
  bool reports_leave_one_out() const override { return basis_ == Basis::kHsh; }
  Result<LinearFitOperator> fit_operator(const std::vector<Vec3d>& directions,
                                         const MapFitOptions& options) const override;
  std::vector<double> sample_parameters(unsigned seed) const override;
  ModelBasis coefficient_basis() const override;  // kSh or kHsh with the bands
  /// ShFitOptions or HshFitOptions valid for the name's bands (and method).
  Status check_options(const MapFitOptions& options) const override;
  std::string options_fingerprint(const MapFitOptions& options) const override;
  Result<ParameterMap> fit_map(const MapFitContext& context) const override;

 private:
  Basis basis_;
  ShFitMethod method_;
  int bands_;
};

/// Registers the "sh-zh", "sh-lsop", "sh-ls" and "hsh" families.
void register_harmonic_models(ModelRegistry& registry);

/// The coefficients (n^2 x 3) of texel (s, t) of an SH or HSH map (checked), and setting them.
Eigen::MatrixXd harmonic_coefficients(const ParameterMap& map, int s, int t);
void set_harmonic_coefficients(ParameterMap& map, int s, int t, const Eigen::MatrixXd& coefficients);

}  // namespace vdrig::fitting

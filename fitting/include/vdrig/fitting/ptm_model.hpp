// Polynomial texture maps (PTM, Malzbender, Gelb & Wolters 2001), the first RTI model and what RTIViewer and the
// PTM file format (rti/ptm_file.hpp) carry: radiance as a biquadratic in the projected light direction
// (lu, lv) = (x, y) of the unit direction v toward the light (here: the direction of the observation),
//
//   f(lu, lv) = a0 lu^2 + a1 lv^2 + a2 lu lv + a3 lu + a4 lv + a5        (PTM's coefficient order)
//
// Two variants, as the format's PTM_FORMAT_RGB and PTM_FORMAT_LRGB:
//  - "ptm:rgb" (also "ptm"): one biquadratic per colour channel, 18 coefficients; channels ptm.R.0 .. ptm.R.5,
//    ptm.G.0 .., ptm.B.0 ..; fitted by least squares, one operator for all texels sharing their directions.
//  - "ptm:lrgb": one biquadratic for the luminance Y = (R + G + B) / 3 times a per-texel chromaticity
//    (R, G, B) / Y: channels ptm.L.0 .. ptm.L.5, chroma.R, chroma.G, chroma.B; radiance_c = f_L(lu, lv) chroma_c.
//    The luminance is fitted by least squares, the chromaticity is sum_j rgb_j / sum_j Y_j over the samples
//    (the colour of the texel's mean), as PTMfitter does. Not linear in the radiance (the chromaticity is a ratio).
//
// Both report leave-one-out errors (loo.R/G/B): exact for ptm:rgb; for ptm:lrgb the luminance's exact LOO
// prediction times the chromaticity of all samples.
#pragma once

#include "vdrig/fitting/model.hpp"

namespace vdrig::fitting {

class PtmModel : public ReflectanceModel {
 public:
  enum class Variant { kRgb, kLrgb };
  explicit PtmModel(Variant variant) : variant_(variant) {}

  Variant variant() const { return variant_; }
  std::string family() const override { return "ptm"; }
  std::string name() const override;
  std::vector<std::string> channels() const override;
  Vec3d evaluate(std::span<const double> parameters, const Vec3d& v) const override;
  std::string glsl(const std::function<std::string(int parameter)>& parameter) const override;
  bool linear_in_shared_directions() const override { return variant_ == Variant::kRgb; }
  Result<LinearFitOperator> fit_operator(const std::vector<Vec3d>& directions,
                                         const MapFitOptions& options) const override;
  bool reports_leave_one_out() const override { return true; }
  std::vector<double> sample_parameters(unsigned seed) const override;
  ModelBasis coefficient_basis() const override;  // kPtmRgb or kPtmLrgb
  Result<ParameterMap> fit_map(const MapFitContext& context) const override;

 private:
  Variant variant_;
};

/// The six PTM basis functions (lu^2, lv^2, lu lv, lu, lv, 1) at a direction; lu, lv are its x and y.
void ptm_basis(const Vec3d& v, double out[6]);

/// Registers the "ptm" family (ptm, ptm:rgb, ptm:lrgb).
void register_ptm_model(ModelRegistry& registry);

}  // namespace vdrig::fitting

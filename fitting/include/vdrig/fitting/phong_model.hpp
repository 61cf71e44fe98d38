// The Phong reflectance model of a parameter map (phong.hpp has the model and its fit): names "phong:K" (K = 1..4
// lobes), "phong:auto" (1..4 lobes chosen per texel by BIC), either with ":per-lobe-m" for one shininess per lobe.
//
// Channels: kd.R/G/B, per lobe k = 0..K-1 ks<k>.R/G/B, r<k>.x/y/z and m<k> (per-lobe shininess), then m (shared
// shininess); phong:auto also "lobes" (the count chosen for the texel; its unused lobes are zero, K = the largest
// count chosen anywhere). Header attributes: vdrig.lobes (K), vdrig.shared_m (1 shared, 0 per lobe).
// Its map fit honours MapFitOptions::model_options' PhongFitOptions (lobes and shininess sharing taken from the
// name) and ::shared_lights (fit_map.hpp); its options_fingerprint is those and the light-estimation options. With
// PhongFitOptions::lobe_support > 0 (the default) the map also has the channel "m_capped": per texel, the lobes whose
// shininess the sampling bounds, so that the surface may be glossier there than the map says (phong.hpp, "Between the
// samples").
#pragma once

#include "vdrig/fitting/model.hpp"
#include "vdrig/fitting/phong.hpp"

namespace vdrig::fitting {

/// The channel of a Phong map that counts a texel's lobes held at the sampling's shininess cap (phong_support_cap).
inline constexpr const char* kCappedLobesChannel = "m_capped";

class PhongModel : public ReflectanceModel {
 public:
  /// lobes 1..4, or 0 with auto_lobes for phong:auto before its lobe count is known.
  PhongModel(int lobes, bool auto_lobes, bool shared_shininess);

  /// K, the lobes a map stores (0: phong:auto not resolved yet, not storable).
  int lobes() const { return lobes_; }
  bool auto_lobes() const { return auto_lobes_; }
  bool shared_shininess() const { return shared_shininess_; }
  /// The same model with K lobes stored (phong:auto once its fit or its file says how many).
  ModelPtr with_lobes(int lobes) const;

  /// A texel's parameters as PhongParams (all K lobes, unused ones with zero Ks), and back (lobes beyond
  /// params.lobes get zero energy; more lobes than K is a broken invariant).
  PhongParams params_of(std::span<const double> parameters) const;
  std::vector<double> parameters_of(const PhongParams& params) const;

  std::string family() const override { return "phong"; }
  std::string name() const override;
  std::vector<std::string> channels() const override;
  bool storable() const override { return lobes_ >= 1; }
  void write_attributes(std::map<std::string, double>& number_attributes) const override;
  Result<ModelPtr> with_attributes(const std::map<std::string, double>& number_attributes) const override;
  Vec3d evaluate(std::span<const double> parameters, const Vec3d& v) const override;
  std::string check_parameters(std::span<const double> parameters) const override;  // m >= 0
  std::string glsl(const std::function<std::string(int parameter)>& parameter) const override;
  bool has_diffuse_part() const override { return true; }
  Vec3d diffuse_part(std::span<const double> parameters) const override;              // Kd
  std::vector<LobeSummary> lobes(std::span<const double> parameters) const override;  // all K, as stored
  std::vector<double> sample_parameters(unsigned seed) const override;
  ModelPtr storable_sample() const override { return storable() ? shared_from_this() : with_lobes(2); }
  /// PhongFitOptions::is_valid, fixed directions against phong:auto and shared_lights, the light options.
  Status check_options(const MapFitOptions& options) const override;
  std::string options_fingerprint(const MapFitOptions& options) const override;
  Result<ParameterMap> fit_map(const MapFitContext& context) const override;
  /// Records hold every texel's fit at full precision; with shared lights a second pass refits the tiles after the
  /// lights are estimated from every tile's lobe rays, gathered in texel order as fit_map gathers them.
  Result<std::unique_ptr<ModelTiledFit>> tiled_fit(const MapFitOptions& options,
                                                   const ObservationMapSpec& spec) const override;

 private:
  int lobes_;
  bool auto_lobes_;
  bool shared_shininess_;
};

/// Registers the "phong" family.
void register_phong_model(ModelRegistry& registry);

/// Texel (s, t) of a Phong map (the map's model must be a PhongModel: checked).
PhongParams phong_texel(const ParameterMap& map, int s, int t);
void set_phong_texel(ParameterMap& map, int s, int t, const PhongParams& params);

}  // namespace vdrig::fitting

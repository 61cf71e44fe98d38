// The GGX microfacet BRDF models ("ggx:iso", "ggx:iso+n" with a per-texel shading normal, "ggx:aniso" with two
// roughnesses and the direction of the rougher one, "ggx:aniso+n" with both): per texel a Lambertian
// albedo, a Fresnel reflectance at normal incidence and a roughness, fitted under the session's light. Unlike the
// view-only models (Phong lobes, SH, HSH, PTM: the radiance toward v under the session's fixed lighting), its
// parameters are a material: GgxModel::brdf gives its reflectance for any light and view, which is what an exported
// material (pipeline/gltf_export.hpp) carries.
//
// The BRDF (docs/models.md, "BRDF models"), the simulator's GGX material (sim/ggx.hpp) and glTF 2.0's specular term:
//   f(l, v)  = albedo / pi + F(v . h) D(h) G2(l, v) / (4 lz vz),   h = (l + v) / |l + v|, zero for lz <= 0 or vz <= 0
//   D(h)     = alpha^2 / (pi (hz^2 (alpha^2 - 1) + 1)^2)             (Trowbridge-Reitz)
//   Lambda(w)= (sqrt(1 + alpha^2 (wx^2 + wy^2) / wz^2) - 1) / 2,  G2 = 1 / (1 + Lambda(l) + Lambda(v))  (height-
//              correlated Smith)
//   F(c)     = f0 + (1 - f0) (1 - c)^5                               (Schlick, per RGB channel)
//   alpha    = roughness^2                                           (glTF's perceptual roughness)
// in the surface frame (normal +z); ggx:iso+n evaluates the same formula in the frame of the texel's shading normal n
// (lz, vz, hz are then l . n, v . n, h . n and wx^2 + wy^2 is 1 - (w . n)^2), and its irradiance is I (l . n) / d^2.
// The radiance a texel sends toward v under a point light is
//   L(v) = E (albedo + pi f_spec(l, v)) = pi E f(l, v),   E = I cos(theta_l) / d^2
// with I the light's intensity in the simulator's relative units (a light of intensity I lights a white Lambertian
// surface facing it at d metres to radiance I / d^2), so that a simulated GGX material of kd, f0 and alpha has
// albedo = kd, the same f0 and roughness = sqrt(alpha).
//
// Channels: albedo.R/G/B, f0.R/G/B, roughness (the material), for ggx:iso+n normal.x/y (the shading normal's tilt:
// its x and y components in the surface frame, z = sqrt(1 - x^2 - y^2)), for ggx:aniso roughness.b and aniso.angle
// (roughness is then the one along the tangent t = (cos angle, sin angle, 0), roughness.b <= roughness the one along
// b = (-sin angle, cos angle, 0), angle in [0, pi) radians from the surface's x axis toward y; D and Lambda are
// sim/ggx.hpp's anisotropic forms with alpha_t = roughness^2, alpha_b = roughness.b^2; ggx:aniso+n has both, aniso's
// two channels then the normal's, its t (cos angle, sin angle, 0) projected onto the normal's plane, b = n x t), then
// light.x/y/z (the unit direction toward the session's light at the texel, surface frame) and E.R/G/B (its
// irradiance there, as above): the fit stores the light per texel so that evaluate() (the radiance under the
// session's light, as for every model) and the viewer render the map as the session saw it. A texel fitted from too
// few observations is all zeros (black).
#pragma once

#include <optional>
#include <string>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/model.hpp"

namespace vdrig::fitting {

/// The session's light as a BRDF fit needs it: one point light fixed to the platform.
struct SessionLight {
  Vec3d position_m = Vec3d(0, 0, 1);  // surface frame (origin at the sample's centre, z up), metres
  Vec3d intensity = Vec3d::Ones();    // RGB, relative units: radiance I / d^2 on a white Lambertian facing it, d in m

  /// The unit direction toward the light from surface point p_m (metres, z = 0) and the irradiance E there
  /// (I cos / d^2, zero when the light is at or below the horizon).
  void at(const Vec3d& p_m, Vec3d* direction, Vec3d* irradiance) const;
  /// "point X Y Z I_R I_G I_B" (metres), the map's vdrig.session_light attribute.
  std::string describe() const;
  /// The problem with the light ("intensity is negative"), or "".
  std::string check() const;
};

/// The fit options of the GGX model (fit_map.hpp's MapFitOptions::model_options).
struct GgxFitOptions {
  std::optional<SessionLight> light;  // required to fit; pipeline's fit stage chooses it (docs/models.md, "The light")
  int max_iterations = 100;           // bounded Levenberg-Marquardt iterations per texel

  std::string fingerprint() const;
};

/// A texel's material (the first seven parameters).
struct GgxMaterial {
  Vec3d albedo = Vec3d::Zero();
  Vec3d f0 = Vec3d::Zero();
  double roughness = 0.0;         // glTF's perceptual roughness; alpha = roughness^2
  Vec3d normal = Vec3d::UnitZ();  // the shading normal (unit, surface frame): +z unless ggx:iso+n
  double roughness_b = 0.0;       // ggx:aniso(+n): the roughness along the bitangent; 0 = isotropic (= roughness)
  double angle = 0.0;             // ggx:aniso(+n): the tangent's angle from the surface's x axis toward y, radians
};

class GgxModel : public ReflectanceModel {
 public:
  static constexpr int kMaterialParameters = 7;  // albedo RGB, f0 RGB, roughness
  static constexpr double kMinRoughness = 0.03;  // the fit's lower bound (alpha 9e-4); evaluation clamps to it too
  static constexpr double kMaxTilt = 0.95;       // ggx:iso+n: normal.x^2 + normal.y^2 at most (tilt <= 77 deg)

  enum class Form { kIso, kIsoNormal, kAniso, kAnisoNormal };
  explicit GgxModel(Form form = Form::kIso)
      : shading_normal_(form == Form::kIsoNormal || form == Form::kAnisoNormal),
        aniso_(form == Form::kAniso || form == Form::kAnisoNormal) {}
  /// ggx:iso+n, ggx:aniso+n: the two normal.x/y channels follow the material's seven (and aniso's two).
  bool has_shading_normal() const { return shading_normal_; }
  /// ggx:aniso, ggx:aniso+n: roughness.b and aniso.angle follow the material's seven.
  bool is_anisotropic() const { return aniso_; }
  std::string family() const override { return "ggx"; }
  std::string name() const override;
  std::vector<std::string> channels() const override;
  Vec3d evaluate(std::span<const double> parameters, const Vec3d& v) const override;
  std::string check_parameters(std::span<const double> parameters) const override;
  bool has_diffuse_part() const override { return true; }
  Vec3d diffuse_part(std::span<const double> parameters) const override;  // E albedo
  std::vector<LobeSummary> lobes(std::span<const double> parameters) const override;
  std::vector<double> sample_parameters(unsigned seed) const override;
  std::string glsl(const std::function<std::string(int parameter)>& parameter) const override;
  Status check_options(const MapFitOptions& options) const override;
  std::string options_fingerprint(const MapFitOptions& options) const override;
  Result<ParameterMap> fit_map(const MapFitContext& context) const override;
  /// The per-texel tiled fit, each tile's texels placed on the whole map (the light's direction depends on it).
  Result<std::unique_ptr<ModelTiledFit>> tiled_fit(const MapFitOptions& options,
                                                   const ObservationMapSpec& spec) const override;

  /// A texel's material from its parameters (ggx:iso's; normal +z).
  static GgxMaterial material(std::span<const double> parameters);
  /// A texel's material from this model's parameters (the shading normal, the second roughness and angle too).
  GgxMaterial texel_material(std::span<const double> parameters) const;
  /// The BRDF f(l, v) (1/sr, per RGB channel) of a material for unit l and v (surface frame; zero below the shading
  /// normal's horizon), as above.
  static Vec3d brdf(const GgxMaterial& material, const Vec3d& l, const Vec3d& v);

 private:
  int normal_channel() const { return kMaterialParameters + (aniso_ ? 2 : 0); }
  int light_channel() const { return normal_channel() + (shading_normal_ ? 2 : 0); }
  int parameter_count() const { return light_channel() + 6; }
  /// fit_map for the texels of `context.spec`, texel (0, 0) being texel (s0, t0) of a map of spec `whole`.
  Result<ParameterMap> fit_region(const MapFitContext& context, int s0, int t0, const ObservationMapSpec& whole) const;
  bool shading_normal_ = false, aniso_ = false;
};

/// Registers the "ggx" family (ggx:iso, ggx:iso+n, ggx:aniso, ggx:aniso+n).
void register_ggx_model(ModelRegistry& registry);

}  // namespace vdrig::fitting

#include "vdrig/pipeline/session_light.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <type_traits>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>

#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/session_layout.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/light_uncertainty.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/rig/geometry_config.hpp"
#include "vdrig/rig/lamp.hpp"

namespace vdrig::pipeline {

fitting::SessionLight unit_centre_irradiance_light(const Vec3d& position_m) {
  // E = I cos / d^2 at the centre, cos = z / d: I = d^3 / z.
  fitting::SessionLight light;
  light.position_m = position_m;
  const double d = position_m.norm();
  light.intensity = Vec3d::Constant(position_m.z() > 0.0 ? d * d * d / position_m.z() : 1.0);
  return light;
}

Result<std::optional<ResolvedSessionLight>> recorded_session_light(const capture::Session& session) {
  const nlohmann::json& rc = session.manifest().rig_config;
  if (!rc.is_object() || !rc.contains("light")) return std::optional<ResolvedSessionLight>();
  auto lamp = rig::lamp_from_light_section(rc["light"]);
  if (!lamp) return lamp.error();
  if (!lamp.value()) return std::optional<ResolvedSessionLight>();
  const rig::LampPosition& l = *lamp.value();
  std::string frame = "surface frame";
  Vec3d position_mm = l.position_mm;
  if (l.frame == rig::LampPosition::Frame::kPlatter) {
    // The surface's offset and tilt on the platter: the kinematic fit when the session has one, else the stated rig.
    auto fitted = rig::read_fitted_geometry(session.layout().views_file());
    if (fitted) {
      frame = "platter frame, through the calibrated geometry";
      position_mm = rig::lamp_in_surface_frame(l, fitted.value());
    } else {
      auto stated = capture::geometry_from_rig_config(rc);
      if (!stated) return stated.error();
      frame = "platter frame, through the rig config's geometry (no kinematic fit: " + fitted.error().message + ")";
      position_mm = rig::lamp_in_surface_frame(l, stated.value());
    }
  }
  ResolvedSessionLight out;
  out.light = unit_centre_irradiance_light(position_mm / 1000.0);
  if (l.intensity) out.light.intensity = *l.intensity * 1e-6;  // I / d_mm^2 = (I 1e-6) / d_m^2
  if (const std::string why = out.light.check(); !why.empty())
    return make_error(ErrorCode::kInvalidArgument, "the rig config's lamp: " + why);
  out.source = fmt::format("the session's rig config: lamp at ({:.1f}, {:.1f}, {:.1f}) mm ({}{}{}), intensity {}",
                           l.position_mm.x(), l.position_mm.y(), l.position_mm.z(), frame, l.source.empty() ? "" : "; ",
                           l.source, l.intensity ? "as stated" : "not stated: 1 at the sample's centre (gauge)");
  return std::optional<ResolvedSessionLight>(std::move(out));
}

double LightEstimate::distance_sigma_mm() const {
  const Vec3d u = light.position_mm.normalized();
  return std::sqrt(std::max(0.0, u.dot(covariance_mm2 * u)));
}

std::string LightEstimate::describe() const {
  const Vec3d& p = light.position_mm;
  const Vec3d sigma = covariance_mm2.diagonal().cwiseMax(0.0).cwiseSqrt();
  return fmt::format(
             "point light at ({:.1f}, {:.1f}, {:.1f}) mm +- ({:.1f}, {:.1f}, {:.1f}) mm, {:.1f} +- {:.1f} mm from the "
             "centre, from {} of {} texel lobes, rms {:.2f} deg",
             p.x(), p.y(), p.z(), sigma.x(), sigma.y(), sigma.z(), p.norm(), distance_sigma_mm(), light.inliers, rays,
             rad_to_deg(light.rms_angle_rad)) +
         (refine_evaluations > 0
              ? fmt::format(" (the lobes' ({:.1f}, {:.1f}, {:.1f}) mm refined by {} ggx:iso fits of {} texels)",
                            phong_position_mm.x(), phong_position_mm.y(), phong_position_mm.z(), refine_evaluations,
                            refine_texels)
              : "");
}

namespace {

constexpr size_t kMaxRays = 20000;  // as the Phong fit's shared-lights pass (phong_map_fit.hpp)

/// At most kRefineTexels a side: the refinement fits ggx:iso some 80 times.
constexpr int kRefineTexels = 16;

/// Every k-th texel of the map (k = ceil(S / kRefineTexels)), each at the centre of its k x k block (half a texel
/// from where it was observed when k is even: ~8 mm at 64 texels a metre, nothing against a light metres away).
template <typename Obs>
Result<fitting::ObservationMap> subsample(const Obs& obs) {
  const fitting::ObservationMapSpec& spec = obs.spec();
  const int k = std::max((spec.texels_s + kRefineTexels - 1) / kRefineTexels,
                         (spec.texels_t + kRefineTexels - 1) / kRefineTexels);
  fitting::ObservationMap sub(
      {std::max(1, spec.texels_s / k), std::max(1, spec.texels_t / k), spec.width_mm, spec.height_mm}, obs.views());
  std::optional<fitting::ObsTile> tile;
  for (int j = 0; j < sub.spec().texels_t; ++j)
    for (int i = 0; i < sub.spec().texels_s; ++i) {
      const int s = std::min(spec.texels_s - 1, i * k + k / 2), t = std::min(spec.texels_t - 1, j * k + k / 2);
      for (int v = 0; v < obs.views(); ++v) {
        Eigen::Vector3f rgb, dir;
        uint8_t flag = 0;
        if constexpr (std::is_same_v<Obs, fitting::ObsMapReader>) {
          if (!tile || !tile->contains(s, t)) {
            auto read = obs.read_tile_of_texel(s, t);
            if (!read) return read.error();
            tile = std::move(read.value());
          }
          flag = tile->observation(s, t, v, &rgb, &dir);
        } else {
          flag = obs.observation(s, t, v, &rgb, &dir);
        }
        sub.set(i, j, v, rgb, dir, flag);
      }
    }
  return sub;
}

/// The ggx:iso fit's squared residuals over the map (sum over texels of n (rms.R^2 + rms.G^2 + rms.B^2)), and the
/// residuals and parameters they count.
struct GgxResidual {
  double ssr = 0;
  double residuals = 0, parameters = 0;
};
Result<GgxResidual> ggx_residual(const fitting::ObservationMap& obs, const std::vector<int>& held_out, int threads,
                                 const Vec3d& position_mm) {
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("ggx:iso").value();
  options.held_out = held_out;
  options.threads = threads;
  options.model_options.edit<fitting::GgxFitOptions>().light = unit_centre_irradiance_light(position_mm / 1000.0);
  auto map = fitting::fit_parameter_map(obs, options);
  if (!map) return map.error();
  GgxResidual out;
  for (int t = 0; t < map->texels_t(); ++t)
    for (int s = 0; s < map->texels_s(); ++s) {
      const double n = map->at("n", s, t);
      if (!(n > 0)) continue;
      for (const char* c : {"rms.R", "rms.G", "rms.B"}) out.ssr += n * std::pow(map->at(c, s, t), 2);
      out.residuals += 3 * n;
      out.parameters += fitting::GgxModel::kMaterialParameters;
    }
  return out;
}

/// The light's position that the ggx:iso fit explains best, from the Phong lobes' estimate: the lobes of a
/// microfacet highlight peak off the mirror direction (Fresnel and masking lean them toward grazing), which put the
/// light ~8-16 % nearer and a few degrees low on the simulator's GGX materials. Nelder-Mead over the light's
/// direction (two angles) and log distance from the centre, minimising the squared residuals of ggx:iso fits of a
/// subsample of the texels (each texel's material profiled out); the covariance from that profile's curvature,
/// 2 sigma^2 H^-1 with H the finite-difference Hessian of the squared residuals in mm and sigma^2 their variance.
template <typename Obs>
Status refine_with_ggx(const Obs& full, const std::vector<int>& held_out, int threads, LightEstimate* out) {
  auto sub = subsample(full);
  if (!sub) return sub.error();
  const fitting::ObservationMap& obs = sub.value();
  using V3 = Eigen::Vector3d;
  const auto to_position = [](const V3& x) { return Vec3d(direction_from_spherical(x[0], x[1]) * std::exp(x[2])); };
  Status failure = Status::ok();
  int evaluations = 0;
  const auto cost = [&](const V3& x) {
    ++evaluations;
    if (!(x[1] > 0.0 && x[1] < deg_to_rad(89.0))) return std::numeric_limits<double>::infinity();
    auto r = ggx_residual(obs, held_out, threads, to_position(x));
    if (!r) {
      failure = r.error();
      return std::numeric_limits<double>::infinity();
    }
    return r->ssr;
  };
  const Vec3d p0 = out->light.position_mm;
  const SphericalDir d0 = spherical_from_direction(p0.normalized());
  std::array<V3, 4> x;
  x[0] = V3(d0.azimuth_rad, d0.zenith_rad, std::log(p0.norm()));
  x[1] = x[0] + V3(deg_to_rad(3.0), 0, 0);
  x[2] = x[0] + V3(0, deg_to_rad(3.0), 0);
  x[3] = x[0] + V3(0, 0, 0.1);
  std::array<double, 4> f;
  for (int i = 0; i < 4; ++i) f[i] = cost(x[i]);
  for (int it = 0; it < 120 && failure; ++it) {
    std::array<int, 4> order = {0, 1, 2, 3};
    std::sort(order.begin(), order.end(), [&](int a, int b) { return f[a] < f[b]; });
    std::array<V3, 4> xs;
    std::array<double, 4> fs;
    for (int i = 0; i < 4; ++i) xs[i] = x[order[i]], fs[i] = f[order[i]];
    x = xs, f = fs;
    double spread = 0;
    for (int i = 1; i < 4; ++i)
      spread = std::max(spread, std::max((x[i] - x[0]).head<2>().cwiseAbs().maxCoeff() / deg_to_rad(0.02),
                                         std::abs(x[i][2] - x[0][2]) / 3e-4));
    if (spread < 1.0) break;
    const V3 centroid = (x[0] + x[1] + x[2]) / 3.0;
    const V3 reflected = centroid + (centroid - x[3]);
    const double fr = cost(reflected);
    if (fr < f[0]) {
      const V3 expanded = centroid + 2.0 * (centroid - x[3]);
      const double fe = cost(expanded);
      if (fe < fr)
        x[3] = expanded, f[3] = fe;
      else
        x[3] = reflected, f[3] = fr;
    } else if (fr < f[2]) {
      x[3] = reflected, f[3] = fr;
    } else {
      const V3 contracted = centroid + 0.5 * (x[3] - centroid);
      const double fc = cost(contracted);
      if (fc < f[3]) {
        x[3] = contracted, f[3] = fc;
      } else {
        for (int i = 1; i < 4; ++i) x[i] = x[0] + 0.5 * (x[i] - x[0]), f[i] = cost(x[i]);
      }
    }
  }
  if (!failure) return failure;
  int best = 0;
  for (int i = 1; i < 4; ++i)
    if (f[i] < f[best]) best = i;
  const Vec3d p = to_position(x[best]);
  // The curvature of the squared residuals at p (central differences, step 0.5 % of the distance).
  auto at = ggx_residual(obs, held_out, threads, p);
  if (!at) return at.error();
  ++evaluations;
  const double h = 0.005 * p.norm();
  const auto ssr = [&](const Vec3d& q) {
    ++evaluations;
    auto r = ggx_residual(obs, held_out, threads, q);
    return r ? r->ssr : std::numeric_limits<double>::quiet_NaN();
  };
  Mat3d hessian;
  for (int i = 0; i < 3; ++i) {
    const Vec3d ei = Vec3d::Unit(i) * h;
    hessian(i, i) = (ssr(p + ei) - 2 * at->ssr + ssr(p - ei)) / (h * h);
    for (int j = 0; j < i; ++j) {
      const Vec3d ej = Vec3d::Unit(j) * h;
      hessian(i, j) = hessian(j, i) =
          (ssr(p + ei + ej) - ssr(p + ei - ej) - ssr(p - ei + ej) + ssr(p - ei - ej)) / (4 * h * h);
    }
  }
  const double sigma2 = at->ssr / std::max(1.0, at->residuals - at->parameters - 3);
  const Eigen::SelfAdjointEigenSolver<Mat3d> eig(hessian);
  out->light.position_mm = p;
  out->light.direction = p.normalized();
  out->refine_evaluations = evaluations;
  out->refine_texels = obs.spec().texels_s * obs.spec().texels_t;
  if (hessian.allFinite() && eig.eigenvalues()[0] > 0.0)
    out->covariance_mm2 = 2.0 * sigma2 * eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() *
                          eig.eigenvectors().transpose();
  else
    log::get("pipeline")
        ->warn(
            "--light estimate: the residuals do not curve at the light (flat or noisy); its "
            "uncertainty is the Phong lobes' only");
  return Status::ok();
}

template <typename Obs>
Result<LightEstimate> estimate(const Obs& obs, const std::vector<int>& held_out, int threads) {
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("phong:1").value();
  options.held_out = held_out;
  options.threads = threads;
  auto map = fitting::fit_parameter_map(obs, options);
  if (!map) return map.error();
  // The shared-lights pass's rays (phong_map_fit.hpp): one per texel whose lobe stands above its diffuse part.
  const fitting::ReflectanceModel& model = map->model();
  std::vector<fitting::LobeRay> rays;
  for (int t = 0; t < map->texels_t(); ++t)
    for (int s = 0; s < map->texels_s(); ++s) {
      if (!(map->at("n", s, t) > 0)) continue;
      const std::vector<double> p = map->parameters(s, t);
      const Vec3d kd = model.diffuse_part(p);
      for (const fitting::LobeSummary& lobe : model.lobes(p))
        if (lobe.peak_rgb.maxCoeff() > 1e-3 * std::max(kd.maxCoeff(), 1e-12))
          rays.push_back(fitting::lobe_ray(
              texel_centre_mm(s, t, map->texels_s(), map->texels_t(), map->width_mm(), map->height_mm()),
              lobe.direction));
    }
  if (rays.size() > kMaxRays) {
    std::vector<fitting::LobeRay> subsample;
    for (size_t k = 0; k < kMaxRays; ++k) subsample.push_back(rays[k * rays.size() / kMaxRays]);
    rays = std::move(subsample);
  }
  const fitting::LightEstimationOptions light_options = options.lights;
  auto lights = fitting::estimate_point_lights(rays, light_options);
  if (!lights) return lights.error();
  if (lights->empty())
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("--light estimate: no point light explains {} texels' highlights (of {} with a "
                                  "lobe): a matte sample or too few views; give the light with --light X,Y,Z",
                                  light_options.min_inliers, rays.size()));
  LightEstimate out;
  out.light = lights->front();
  out.rays = static_cast<int>(rays.size());
  if (out.light.at_infinity)
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("--light estimate: the texels' highlights point at a distant light toward ({:.3f}, "
                                  "{:.3f}, {:.3f}) with no measurable distance; give the light with --light X,Y,Z",
                                  out.light.direction.x(), out.light.direction.y(), out.light.direction.z()));
  if (lights->size() > 1)
    log::get("pipeline")
        ->warn(
            "--light estimate: {} lights found; the BRDF fit takes one point light, the one most "
            "texels see ({} lobes)",
            lights->size(), out.light.inliers);
  auto covariance = fitting::light_position_covariance(rays, out.light, light_options);
  if (!covariance) return covariance.error();
  out.covariance_mm2 = covariance.value();
  out.phong_position_mm = out.light.position_mm;
  out.phong_covariance_mm2 = out.covariance_mm2;
  VDRIG_TRY(refine_with_ggx(obs, held_out, threads, &out));
  out.session_light = unit_centre_irradiance_light(out.light.position_mm / 1000.0);
  return out;
}

}  // namespace

Result<LightEstimate> estimate_session_light(const fitting::ObsMapReader& obs, const std::vector<int>& held_out,
                                             int threads) {
  return estimate(obs, held_out, threads);
}

Result<LightEstimate> estimate_session_light(const fitting::ObservationMap& obs, const std::vector<int>& held_out,
                                             int threads) {
  return estimate(obs, held_out, threads);
}

}  // namespace vdrig::pipeline

#include "vdrig/pipeline/adaptive_stage.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/core.hpp>

#include "vdrig/capture/route.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/pipeline/session_light.hpp"
#include "vdrig/rig/lamp.hpp"

namespace vdrig::pipeline {
namespace {

/// Views a lobe's support cone should hold before its width counts as measured: docs/sampling.md, "adaptive".
constexpr double kWantedLobeViews = 6.0;
/// Lobes per texel the planner fits (each kept only where the observations support it).
constexpr int kPlannerLobes = 2;
/// Lobes broader than this (support cone of 37 deg half-angle) are left to the coverage term.
constexpr double kNarrowLobeShininess = 10.0;
/// Candidate directions: an equal-area jittered grid (stratified, seeded) of this many rows and columns.
constexpr int kCandidateRows = 24, kCandidateColumns = 64;
/// Angle (rad) at which a coverage gap counts fully; larger gaps count as this (a gap is about a spacing).
constexpr double kGapRad = 10.0 * kPi / 180.0, kGapCapRad = 30.0 * kPi / 180.0;
/// Candidates closer than this to a view taken or chosen are not taken again.
constexpr double kMinSeparationRad = 1.5 * kPi / 180.0;
/// model=ggx without a lamp: what to give.
constexpr std::string_view kGgxNeedsLamp =
    "adaptive sampling, model=ggx: the planner fits ggx:iso under the session's lamp, and the rig config records "
    "none: give its \"light\" section the lamp's position (\"position_mm\", docs/hardware.md), or plan with "
    "model=phong";
/// Mirror probes (docs/sampling.md, "adaptive"): a texel with no lobe near an estimated light's mirror direction gets
/// a hypothetical lobe there of this shininess (support cone 7 deg) and weight, until one view falls in its cone.
constexpr double kProbeShininess = 300.0, kProbeWeight = 0.2;
/// Two models disagree (docs/sampling.md, "adaptive"): the weight of the mean over texels of (Phong - quadratic)^2 /
/// brightness^2 at a candidate against the lobe term (0: off). Tuned on adaptive:60, seeds 1-6 (docs/results.md §11):
/// 0.03 and more took views off a lone narrow highlight (tests/pipeline/test_adaptive.cpp).
constexpr double kDisagreeWeight = 0.01;
/// A texel's fitted lobe (of any width) this close to the mirror direction already accounts for that highlight.
constexpr double kProbeKnownRad = 10.0 * kPi / 180.0;

double luminance(const Eigen::Vector3f& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }
double luminance(const Vec3d& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

/// A view's radiance from its frames, merged without a response curve: per pixel, the most exposed frame where it is
/// below the top code, codes / (max code * exposure * gain); pixels clipped in every frame are masked.
fitting::ViewInput view_input(const capture::Session& session, int view, const CameraModel& camera,
                              const rig::RigGeometry& geometry, Status* error) {
  fitting::ViewInput in;
  in.camera = camera;
  auto frames = session.frames_of_view(view);
  if (frames.empty()) {
    *error = make_error(ErrorCode::kNotFound, "view " + std::to_string(view) + " has no frame");
    return in;
  }
  std::stable_sort(frames.begin(), frames.end(), [](const capture::FrameRecord& x, const capture::FrameRecord& y) {
    return x.exposure_s > y.exposure_s;
  });
  for (const auto& f : frames) {
    auto image = session.load_image(f);
    if (!image) {
      *error = image.error();
      return in;
    }
    const double max_code = image->depth() == CV_16U ? 65535.0 : 255.0;
    cv::Mat bgr;
    if (image->channels() == 1) {
      cv::merge(std::vector<cv::Mat>{image.value(), image.value(), image.value()}, bgr);
    } else {
      bgr = image.value();
    }
    cv::Mat codes;
    bgr.convertTo(codes, CV_32FC3);
    if (in.radiance_bgr.empty()) {
      in.radiance_bgr = cv::Mat::zeros(bgr.rows, bgr.cols, CV_32FC3);
      in.clip_mask = cv::Mat(bgr.rows, bgr.cols, CV_8UC1, cv::Scalar(255));
    }
    if (codes.size() != in.radiance_bgr.size()) continue;
    const float scale = static_cast<float>(1.0 / (max_code * f.exposure_s * std::max(f.gain, 1e-9)));
    const float top = static_cast<float>(max_code) - 0.5f;
    for (int y = 0; y < codes.rows; ++y)
      for (int x = 0; x < codes.cols; ++x) {
        if (!in.clip_mask.at<uint8_t>(y, x)) continue;  // a more exposed frame had it unclipped
        const cv::Vec3f& c = codes.at<cv::Vec3f>(y, x);
        if (c[0] >= top || c[1] >= top || c[2] >= top) continue;
        in.radiance_bgr.at<cv::Vec3f>(y, x) = c * scale;
        in.clip_mask.at<uint8_t>(y, x) = 0;
      }
  }
  in.pose = rig::surface_pose(geometry, frames.front().measured);
  return in;
}

struct TexelLobe {
  Vec3d point_mm = Vec3d::Zero();
  Vec3d direction = Vec3d::UnitZ();
  double shininess = 1;
  double weight = 0;   // how much the lobe matters: its share of the texel's brightness
  double in_cone = 0;  // observations inside its support cone (and views chosen into it since)
  bool capped = false;
  bool probe = false;  // a hypothetical narrow lobe at the mirror direction of an estimated light
  /// What one more view in the cone is worth: the variance of a lobe's fit falls about as 1 / n with n views in its
  /// cone, so its need is want / (want + n): 1 with none, 1/2 at kWantedLobeViews, never 0. A lobe whose width the
  /// sampling capped is narrower than the fit can say: at least 1/2.
  double need() const {
    if (probe) return in_cone > 0 ? 0.0 : 1.0;
    const double need = kWantedLobeViews / (kWantedLobeViews + in_cone);
    return capped ? std::max(need, 0.5) : need;
  }
  bool poorly_constrained() const { return !probe && (capped || in_cone < kWantedLobeViews); }
};

/// What the planner keeps of a fitted texel for the mirror probes: where it is, its lobes' axes, where it was seen
/// from.
struct TexelSeen {
  Vec3d point_mm = Vec3d::Zero();
  std::vector<Vec3d> lobe_axes;
  std::vector<Vec3d> seen;
};

/// Mirror probes: the narrow lobes' axes say where the lights are (fitting::estimate_point_lights; capped lobes too,
/// and loose tolerances: the planner's coarse fits miss the axis by a few degrees); each texel with no fitted lobe near
/// a light's mirror direction gets a hypothetical narrow lobe there, so that a highlight narrower than the base's
/// spacing (the bands m = 227 and 500 of patchwork) or lit by a second light the base missed is looked for once.
std::vector<TexelLobe> mirror_probes(const std::vector<fitting::LobeRay>& rays, const std::vector<TexelSeen>& texels,
                                     int* lights_found) {
  std::vector<TexelLobe> probes;
  *lights_found = 0;
  if (rays.size() < 4) return probes;
  fitting::LightEstimationOptions options;
  options.inlier_angle_rad = deg_to_rad(3.0);
  options.exclusion_angle_rad = deg_to_rad(8.0);
  options.min_inliers = 4;
  auto lights = fitting::estimate_point_lights(rays, options);
  if (!lights) return probes;
  *lights_found = static_cast<int>(lights->size());
  const double probe_cos = std::pow(fitting::kLobeSupportLevel, 1.0 / kProbeShininess);
  for (const auto& light : lights.value())
    for (const auto& texel : texels) {
      const Vec3d r = fitting::mirror_direction_at(light, texel.point_mm);
      bool known = false;
      for (const auto& axis : texel.lobe_axes) known = known || axis.dot(r) >= std::cos(kProbeKnownRad);
      if (known) continue;
      TexelLobe probe;
      probe.point_mm = texel.point_mm;
      probe.direction = r;
      probe.shininess = kProbeShininess;
      probe.weight = kProbeWeight;
      probe.probe = true;
      for (const auto& d : texel.seen)
        if (d.dot(r) >= probe_cos) probe.in_cone += 1;
      probes.push_back(probe);
    }
  return probes;
}

/// The intrinsics the planner projects with: camera=FILE.yml of the scheme, or the session's calib/camera.yml.
Result<CameraModel> planner_camera(const capture::AdaptiveSettings& a, const std::filesystem::path& session_dir) {
  const auto path =
      a.camera.empty() ? capture::SessionLayout(session_dir).camera_file() : std::filesystem::path(a.camera);
  auto camera = CameraModel::load_yaml(path);
  if (!camera)
    return make_error(camera.error().code,
                      "adaptive sampling projects with the camera's intrinsics: " + camera.error().message +
                          " (give camera=FILE.yml in the scheme, from `vdrig calib intrinsics`)");
  return camera;
}

/// The lobes of the coarse map's texels that views have to find, and the predicted held-out error's sums: what a
/// planner model (phong or ggx, AdaptiveSettings::model) gives the rest of the planner, which is the same for both.
struct TexelLobes {
  std::vector<TexelLobe> lobes;
  double err2 = 0, sig2 = 0;           // luminance: (predicted - seen)^2 and seen^2 over the held-out observations
  std::vector<TexelSeen> texels_seen;  // for the mirror probes (model=phong; empty: no probes)
  std::vector<fitting::LobeRay> rays;  // the narrow lobes' lines toward their light
  /// Two models per texel for the disagreement term (model=phong): the Phong fit and a quadratic in the direction.
  struct TwoModels {
    Vec3d point_mm = Vec3d::Zero();
    fitting::PhongParams phong;
    Eigen::Matrix<double, 10, 1> quadratic = Eigen::Matrix<double, 10, 1>::Zero();
    double norm2 = 1;  // mean seen luminance^2
  };
  std::vector<TwoModels> models;
};

/// The quadratic basis in a direction: 1, x, y, z, and the six products.
Eigen::Matrix<double, 10, 1> quadratic_basis(const Vec3d& d) {
  Eigen::Matrix<double, 10, 1> b;
  b << 1, d.x(), d.y(), d.z(), d.x() * d.x(), d.y() * d.y(), d.z() * d.z(), d.x() * d.y(), d.x() * d.z(), d.y() * d.z();
  return b;
}

/// Counts the observations inside the lobe's support cone (cos^m >= kLobeSupportLevel).
void count_in_cone(TexelLobe& tl, const fitting::TexelObservations& all) {
  const double cone_cos = std::pow(fitting::kLobeSupportLevel, 1.0 / std::max(1.0, tl.shininess));
  for (size_t i = 0; i < all.size(); ++i)
    if (all.direction[i].cast<double>().dot(tl.direction) >= cone_cos) tl.in_cone += 1;
}

/// model=phong: per texel up to kPlannerLobes Phong lobes; the narrow ones.
Result<TexelLobes> phong_texel_lobes(const fitting::ObservationMap& map, const std::vector<int>& held,
                                     const capture::AdaptiveSettings& a) {
  const fitting::ObservationMapSpec& spec = map.spec();
  TexelLobes out;
  std::vector<TexelLobe>& lobes = out.lobes;
  double& err2 = out.err2;
  double& sig2 = out.sig2;
  // Two lobes where the texel's observations support them (the fit's BIC and detection rules): a scene lit by two
  // lights has two highlights per texel, and one lobe would leave the weaker one to the coverage term.
  fitting::PhongFitOptions phong;
  phong.lobes = kPlannerLobes;
  for (int t = 0; t < a.res; ++t)
    for (int s = 0; s < a.res; ++s) {
      const fitting::TexelObservations all = map.texel(s, t);
      if (all.size() < 4) continue;
      // Predicted error: the fit without the held-out views, at them.
      const fitting::TexelObservations fit_obs = map.texel(s, t, held);
      if (fit_obs.size() >= 4 && fit_obs.size() < all.size()) {
        const fitting::PhongFit before = fitting::fit_phong(fit_obs, phong);
        for (size_t i = 0; i < all.size(); ++i) {
          if (!std::binary_search(held.begin(), held.end(), all.view[i])) continue;
          const double predicted = luminance(before.params.evaluate(all.direction[i].cast<double>()));
          const double seen = luminance(all.radiance[i]);
          err2 += (predicted - seen) * (predicted - seen);
          sig2 += seen * seen;
        }
      }
      const fitting::PhongFit fit = fitting::fit_phong(all, phong);
      double brightness = luminance(fit.params.kd);
      for (const auto& lobe : fit.params.lobes) brightness += luminance(lobe.ks);
      TexelSeen ts;
      ts.point_mm = texel_centre_mm(s, t, a.res, a.res, spec.width_mm, spec.height_mm);
      for (size_t i = 0; i < all.size(); ++i) ts.seen.push_back(all.direction[i].cast<double>());
      for (const auto& lobe : fit.params.lobes) ts.lobe_axes.push_back(lobe.direction.normalized());
      out.texels_seen.push_back(std::move(ts));
      if (all.size() >= 10) {
        TexelLobes::TwoModels m;
        m.point_mm = texel_centre_mm(s, t, a.res, a.res, spec.width_mm, spec.height_mm);
        m.phong = fit.params;
        Eigen::MatrixXd A(all.size(), 10);
        Eigen::VectorXd y(all.size());
        double n2 = 0;
        for (size_t i = 0; i < all.size(); ++i) {
          A.row(static_cast<Eigen::Index>(i)) = quadratic_basis(all.direction[i].cast<double>()).transpose();
          y(static_cast<Eigen::Index>(i)) = luminance(all.radiance[i]);
          n2 += y(static_cast<Eigen::Index>(i)) * y(static_cast<Eigen::Index>(i));
        }
        m.norm2 = std::max(1e-12, n2 / static_cast<double>(all.size()));
        // Ridge: a texel with few views should not swing wildly between them.
        const Eigen::MatrixXd AtA =
            A.transpose() * A + 1e-3 * static_cast<double>(all.size()) * Eigen::MatrixXd::Identity(10, 10);
        m.quadratic = AtA.ldlt().solve(A.transpose() * y);
        out.models.push_back(m);
      }
      for (const auto& lobe : fit.params.lobes) {
        // A broad lobe is measured by any spread of views; only a narrow one needs views placed on it.
        if (lobe.shininess < kNarrowLobeShininess) continue;
        TexelLobe tl;
        tl.point_mm = texel_centre_mm(s, t, a.res, a.res, spec.width_mm, spec.height_mm);
        tl.direction = lobe.direction.normalized();
        tl.shininess = lobe.shininess;
        tl.weight = luminance(lobe.ks) / std::max(1e-12, brightness);
        tl.capped = fit.capped_lobes > 0;
        count_in_cone(tl, all);
        out.rays.push_back(fitting::lobe_ray(tl.point_mm, tl.direction, tl.weight));
        lobes.push_back(tl);
      }
    }
  return out;
}

/// The lowest roughness a ggx:iso fit of a texel may take from these views (fitting/src/ggx_model.cpp,
/// ggx_supported_roughness: D at the half vector nearest the normal at least half its peak): the GGX counterpart of a
/// Phong lobe's support cap.
double ggx_roughness_floor(const Vec3d& light, const fitting::TexelObservations& all) {
  double cos_max = 0.0;
  for (size_t i = 0; i < all.size(); ++i) {
    const Vec3d v = all.direction[i].cast<double>().normalized();
    if (v.z() > 0.0) cos_max = std::max(cos_max, std::min((light + v).normalized().z(), 1.0));
  }
  const double sin2 = 1.0 - cos_max * cos_max;
  const double alpha = std::sqrt(sin2 / (std::sqrt(2.0) - cos_max * cos_max));
  return std::clamp(std::sqrt(alpha), fitting::GgxModel::kMinRoughness, 1.0);
}

/// model=ggx: per texel ggx:iso under the lamp the session recorded (one lobe, no Fresnel "lobe" at grazing: the
/// second Phong lobe spent views on GGX's grazing rise, docs/results.md §11). Its lobe for the planner: axis the
/// light's mirror direction about the normal; width the Phong shininess of the same support cone,
/// m = 1 / (2 alpha^2 cos(light zenith)) (D ~ a Cauchy-like bump of half-vector angle alpha, the view turns twice the
/// half vector, and across the plane of incidence the lobe narrows by cos(light zenith): docs/sampling.md);
/// weight the lobe's share of the texel's radiance over the hemisphere; capped when the roughness sits at the floor
/// the views set.
Result<TexelLobes> ggx_texel_lobes(const capture::Session& session, const fitting::ObservationMap& map,
                                   const std::vector<int>& held, const capture::AdaptiveSettings& a) {
  auto recorded = recorded_session_light(session);
  if (!recorded) return recorded.error();
  if (!recorded.value()) return make_error(ErrorCode::kInvalidArgument, std::string(kGgxNeedsLamp));
  const fitting::SessionLight light = recorded.value()->light;
  const fitting::ObservationMapSpec& spec = map.spec();
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("ggx:iso").value();
  options.model_options.edit<fitting::GgxFitOptions>().light = light;
  options.threads = 1;  // the planner's other fits run on one thread too; texels are few
  options.min_observations = 4;
  TexelLobes out;
  // Predicted error: the fit without the held-out views, at them.
  if (!held.empty()) {
    fitting::MapFitOptions before_options = options;
    before_options.held_out = held;
    auto before = fitting::fit_parameter_map(map, before_options);
    if (!before) return before.error();
    for (int t = 0; t < a.res; ++t)
      for (int s = 0; s < a.res; ++s) {
        if (!(before->at("n", s, t) >= 4)) continue;
        const std::vector<double> p = before->parameters(s, t);
        const fitting::TexelObservations all = map.texel(s, t);
        for (size_t i = 0; i < all.size(); ++i) {
          if (!std::binary_search(held.begin(), held.end(), all.view[i])) continue;
          const double predicted = luminance(before->model().evaluate(p, all.direction[i].cast<double>()));
          const double seen = luminance(all.radiance[i]);
          out.err2 += (predicted - seen) * (predicted - seen);
          out.sig2 += seen * seen;
        }
      }
  }
  auto fitted = fitting::fit_parameter_map(map, options);
  if (!fitted) return fitted.error();
  const fitting::ReflectanceModel& model = fitted->model();
  for (int t = 0; t < a.res; ++t)
    for (int s = 0; s < a.res; ++s) {
      if (!(fitted->at("n", s, t) >= 4)) continue;
      const std::vector<double> p = fitted->parameters(s, t);
      const auto summaries = model.lobes(p);  // the mirror direction about the normal, or none (light below)
      if (summaries.empty()) continue;
      const Vec3d axis = summaries.front().direction.normalized();
      const double fitted_roughness = fitting::GgxModel::material(p).roughness;
      const double roughness = std::max(fitted_roughness, fitting::GgxModel::kMinRoughness),
                   alpha = roughness * roughness;
      TexelLobe tl;
      tl.point_mm = texel_centre_mm(s, t, a.res, a.res, spec.width_mm, spec.height_mm);
      Vec3d l, irradiance;
      light.at(tl.point_mm / 1000.0, &l, &irradiance);
      tl.direction = axis;
      tl.shininess = 1.0 / (2.0 * alpha * alpha * std::max(l.z(), 0.1));
      // A broad lobe is measured by any spread of views; only a narrow one needs views placed on it.
      if (tl.shininess < kNarrowLobeShininess) continue;
      // Its share of the texel's radiance summed over the view hemisphere (a lobe of peak P and shininess m holds
      // about 2 pi P / (m + 1), a diffuse part D holds 2 pi D), not of the peak: a plastic's narrow highlight is nearly
      // all of its peak but little of what an error over the hemisphere weighs (docs/sampling.md, measured).
      const double lobe = luminance(summaries.front().peak_rgb) / (tl.shininess + 1.0);
      tl.weight = lobe / std::max(1e-12, lobe + luminance(model.diffuse_part(p)));
      const fitting::TexelObservations all = map.texel(s, t);
      tl.capped = fitted_roughness <= ggx_roughness_floor(l, all) * (1.0 + 1e-3);
      count_in_cone(tl, all);
      out.lobes.push_back(tl);
    }
  return out;
}

class CoarseFitPlanner final : public capture::ViewPlanner {
 public:
  Status check(const capture::AdaptiveSettings& a, const std::filesystem::path& session_dir,
               const nlohmann::json& rig_config) const override {
    // A new session has no calib/ yet: then the intrinsics must come with the scheme (camera=FILE.yml).
    VDRIG_TRY(planner_camera(a, session_dir).status());
    if (a.model == "ggx") {
      // ggx:iso is a BRDF: the planner fits it under the lamp the rig config records (not estimated per batch).
      if (!rig_config.is_object() || !rig_config.contains("light"))
        return make_error(ErrorCode::kInvalidArgument, std::string(kGgxNeedsLamp));
      auto lamp = rig::lamp_from_light_section(rig_config["light"]);
      if (!lamp) return make_error(lamp.error().code, "adaptive sampling, model=ggx: " + lamp.error().message);
      if (!lamp.value()) return make_error(ErrorCode::kInvalidArgument, std::string(kGgxNeedsLamp));
    }
    return Status::ok();
  }
  Result<capture::BatchPlan> plan_batch(const capture::BatchRequest& req) override {
    auto logger = log::get("pipeline");
    const auto start = std::chrono::steady_clock::now();
    const capture::Session& session = *req.session;
    const capture::AdaptiveSettings& a = req.settings;
    auto camera = planner_camera(a, session.dir());
    if (!camera) return camera.error();
    // The coarse observation map of every complete view.
    std::vector<int> views;
    for (const auto& v : session.manifest().views)
      if (session.view_complete(v.index)) views.push_back(v.index);
    if (views.empty()) return make_error(ErrorCode::kInvalidArgument, "adaptive planning needs captured views");
    fitting::ObservationMapSpec spec;
    spec.texels_s = spec.texels_t = a.res;
    spec.width_mm = session.manifest().surface_width_mm;
    spec.height_mm = session.manifest().surface_height_mm;
    fitting::ObservationMap map(spec, static_cast<int>(views.size()));
    for (size_t k = 0; k < views.size(); ++k) {
      Status error = Status::ok();
      const fitting::ViewInput input = view_input(session, views[k], camera.value(), req.geometry, &error);
      if (!error) return error.error();
      fitting::add_view(map, static_cast<int>(k), input);
      // The planner keeps the grazing samples the observation map flags kObsCoarse (docs/sampling.md, "Grazing
      // views"): their blur biases a texel's final fit, but here they tell the coarse fits which directions were seen
      // and where the highlights are, which is what the planner was tuned on (without them the narrow-highlight test
      // put 10 of 23 views in the cone, not 12).
      for (int t = 0; t < spec.texels_t; ++t)
        for (int s = 0; s < spec.texels_s; ++s) {
          if (map.flag(s, t, static_cast<int>(k)) != fitting::kObsCoarse) continue;
          const Vec3d p = texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
          const Vec2d px = input.camera.project(input.pose.to_camera(p));
          Eigen::Vector3f rgb;
          if (!fitting::sample_bilinear(input.radiance_bgr, px.x(), px.y(), &rgb)) continue;
          if (!input.clip_mask.empty() &&
              input.clip_mask.at<uint8_t>(static_cast<int>(std::lround(px.y())), static_cast<int>(std::lround(px.x()))))
            continue;
          map.set(s, t, static_cast<int>(k), rgb, input.pose.view_direction(p).cast<float>(), fitting::kObsValid);
        }
    }
    // Held out for the predicted error: the last batch (what the fit before it predicted there), or, after the base,
    // every fourth base view.
    std::vector<int> held;  // map view indices, sorted
    for (size_t k = 0; k < views.size(); ++k) {
      const bool in_last =
          std::find(req.previous_batch.begin(), req.previous_batch.end(), views[k]) != req.previous_batch.end();
      if (req.previous_batch.empty() ? k % 4 == 2 : in_last) held.push_back(static_cast<int>(k));
    }
    auto fit = a.model == "ggx" ? ggx_texel_lobes(session, map, held, a) : phong_texel_lobes(map, held, a);
    if (!fit) return fit.error();
    std::vector<TexelLobe>& lobes = fit->lobes;
    const double err2 = fit->err2, sig2 = fit->sig2;
    int poorly = 0;
    for (const auto& l : lobes) poorly += l.poorly_constrained() ? 1 : 0;
    const double predicted_error = sig2 > 0 ? std::sqrt(err2 / sig2) : 0.0;
    // The probes count as lobes for the picks but not in the mean over lobes: they add to the value, not dilute it.
    const size_t real_lobes = lobes.size();
    int lights_found = 0;
    const std::vector<TexelLobe> probes = mirror_probes(fit->rays, fit->texels_seen, &lights_found);
    lobes.insert(lobes.end(), probes.begin(), probes.end());
    int probes_open = 0;
    for (const auto& p : probes) probes_open += p.need() > 0;

    // Candidates the stage reaches, away from the views taken.
    std::vector<Vec3d> taken;
    for (const auto& v : session.manifest().views) taken.push_back(v.direction);
    const auto grid = capture::stratified_directions(kCandidateRows, kCandidateColumns, a.seed + req.batch,
                                                     a.max_zenith_deg * kPi / 180.0);
    const capture::TargetPlan reach = capture::plan_targets(req.geometry, req.stage, grid, req.from.pan_rad);
    struct Candidate {
      Vec3d direction;
      PanTilt target;
      std::vector<Vec3d> texel_dirs;  // per lobe texel: the direction the texel sees the camera from
      bool used = false;
      double disagree = 0;  // mean over texels of (phong - quadratic)^2 / brightness^2 there
    };
    const double disagree_weight = a.model == "phong" ? kDisagreeWeight : 0.0;
    std::vector<Candidate> cands;
    for (const auto& r : reach.reachable) {
      Candidate c{r.direction, r.pan_tilt, {}, false};
      const ViewPose pose = rig::surface_pose(req.geometry, r.pan_tilt);
      for (const auto& l : lobes) c.texel_dirs.push_back(pose.view_direction(l.point_mm));
      if (disagree_weight > 0 && !fit->models.empty()) {
        for (const auto& m : fit->models) {
          const Vec3d d = pose.view_direction(m.point_mm);
          if (d.z() <= 0) continue;
          const double diff = luminance(m.phong.evaluate(d)) - m.quadratic.dot(quadratic_basis(d));
          c.disagree += diff * diff / m.norm2;
        }
        c.disagree /= static_cast<double>(fit->models.size());
      }
      cands.push_back(std::move(c));
    }
    auto gap_of = [&](const Vec3d& d) {
      double best = kPi;
      for (const auto& v : taken) best = std::min(best, std::acos(std::clamp(d.dot(v), -1.0, 1.0)));
      return best;
    };
    auto lobe_value = [&](const TexelLobe& l, const Vec3d& dir) {
      const double c = dir.dot(l.direction);
      return c > 0 ? std::pow(c, l.shininess) : 0.0;
    };
    capture::BatchPlan plan;
    plan.predicted_error = predicted_error;
    PanTilt at = req.from;
    std::vector<PanTilt> route;  // ahead > 1: the picks so far, each inserted where it adds the least move time
    double lobe_total = 0, coverage_total = 0, disagree_total = 0;
    for (int pick = 0; pick < req.max_views; ++pick) {
      int best = -1;
      double best_utility = 0, best_lobe = 0, best_cov = 0, best_dis = 0;
      for (size_t i = 0; i < cands.size(); ++i) {
        Candidate& c = cands[i];
        if (c.used) continue;
        const double gap = gap_of(c.direction);
        if (gap < kMinSeparationRad) continue;
        double lobe_term = 0;
        for (size_t k = 0; k < lobes.size(); ++k)
          lobe_term += lobes[k].weight * lobes[k].need() * lobe_value(lobes[k], c.texel_dirs[k]);
        // Per texel with a lobe: up to 1 when every lobe needs views and the candidate sits on their axes.
        lobe_term /= static_cast<double>(std::max<size_t>(real_lobes, 1));
        const double g = std::min(gap, kGapCapRad) / kGapRad;
        const double cov_term = a.coverage_weight * g * g / 9.0;  // 1 at the capped gap
        // Two models disagree: resolved by a view within about a gap spacing (kGapRad) of the candidate.
        const double gd = std::min(gap, kGapRad) / kGapRad;
        const double dis_term = disagree_weight * c.disagree * gd * gd;
        const double value = lobe_term + cov_term + dis_term;
        const double move_s = a.ahead > 1 ? capture::cheapest_insertion(req.stage, req.from, route, c.target).added_s
                                          : capture::move_time_s(req.stage, at, c.target);
        const double utility = value / (1.0 + move_s / a.move_weight_s);
        if (utility > best_utility) {
          best_utility = utility;
          best = static_cast<int>(i);
          best_lobe = lobe_term;
          best_cov = cov_term;
          best_dis = dis_term;
        }
      }
      if (best < 0 || best_utility < 1e-9) break;
      Candidate& c = cands[best];
      c.used = true;
      plan.directions.push_back(c.direction);
      taken.push_back(c.direction);
      at = c.target;
      if (a.ahead > 1) {
        const auto into = capture::cheapest_insertion(req.stage, req.from, route, c.target);
        route.insert(route.begin() + static_cast<std::ptrdiff_t>(into.position), c.target);
      }
      lobe_total += best_lobe;
      coverage_total += best_cov;
      disagree_total += best_dis;
      for (size_t k = 0; k < lobes.size(); ++k)
        if (lobe_value(lobes[k], c.texel_dirs[k]) >= fitting::kLobeSupportLevel) lobes[k].in_cone += 1;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    plan.info = {{"views_fitted", views.size()},     {"held_out", held.size()},    {"texels_with_lobe", real_lobes},
                 {"poorly_constrained", poorly},     {"lobe_value", lobe_total},   {"coverage_value", coverage_total},
                 {"lights_estimated", lights_found}, {"probes_open", probes_open}, {"planning_s", seconds},
                 {"disagree_value", disagree_total}};
    logger->info(
        "adaptive plan {}: {} views fitted, {} lobes ({} poorly constrained), {} lights estimated, {} mirror probes "
        "open, predicted error {:.4g}, {:.2f} s",
        req.batch, views.size(), real_lobes, poorly, lights_found, probes_open, predicted_error, seconds);
    return plan;
  }
};

}  // namespace

std::unique_ptr<capture::ViewPlanner> make_coarse_fit_planner() { return std::make_unique<CoarseFitPlanner>(); }

void register_adaptive_planner() { capture::register_view_planner_factory(make_coarse_fit_planner); }

}  // namespace vdrig::pipeline

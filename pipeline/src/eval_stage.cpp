#include "vdrig/pipeline/eval_stage.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <opencv2/core/utility.hpp>

#include "vdrig/capture/session.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::pipeline {

Result<std::optional<GroundTruth>> ground_truth_of(const nlohmann::json& rig_config) {
  if (!rig_config.contains("sim")) return std::optional<GroundTruth>();
  auto config = sim::SimConfig::from_json(rig_config["sim"]);
  if (!config) return config.error();
  auto scene = sim::make_scene(config->scene);
  if (!scene) return scene.error();
  GroundTruth truth;
  truth.camera = config->camera;
  truth.geometry = config->geometry;
  truth.response = config->sensor.response;
  truth.markers.centres_mm = scene->marker_centres_mm();
  if (!scene->markers.empty()) truth.markers.radius_mm = scene->markers.front().radius_mm;
  truth.surface_width_mm = scene->width_mm;
  truth.surface_height_mm = scene->height_mm;
  return std::optional<GroundTruth>(std::move(truth));
}

std::optional<sim::Scene> simulated_scene_of(const nlohmann::json& rig_config) {
  if (!rig_config.is_object() || !rig_config.contains("sim")) return std::nullopt;
  auto config = sim::SimConfig::from_json(rig_config["sim"]);
  if (!config) return std::nullopt;
  auto scene = sim::make_scene(config->scene);
  if (!scene) return std::nullopt;
  return std::optional<sim::Scene>(std::move(scene.value()));
}

namespace {

constexpr float kOutside = -1.0f, kMixed = -2.0f;

// Per-channel sums of map x truth, truth^2 and map^2 of a texel over a set of directions: its relative RMS after
// any per-channel scale of the map follows from them (ChannelSums::relative_rms).
struct ChannelSums {
  Vec3d mt = Vec3d::Zero(), tt = Vec3d::Zero(), mm = Vec3d::Zero();

  /// sqrt(sum_c sum_v (L_map / k_c - L_true)^2 / sum_c sum_v L_true^2); NaN when the truth is black.
  double relative_rms(const Vec3d& k = Vec3d::Ones()) const {
    const double truth2 = tt.sum();
    if (!(truth2 > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    double err2 = 0.0;
    for (int c = 0; c < 3; ++c) err2 += mm[c] / (k[c] * k[c]) - 2.0 * mt[c] / k[c] + tt[c];
    return std::sqrt(std::max(err2, 0.0) / truth2);
  }
};

ChannelSums channel_sums(const fitting::ParameterMap& map, int s, int t, const sim::Scene& scene, const Vec3d& p,
                         const std::vector<Vec3d>& directions) {
  ChannelSums out;
  for (const Vec3d& v : directions) {
    const Vec3d truth = scene.radiance(p, v), fit = map.evaluate(s, t, v);
    out.mt += fit.cwiseProduct(truth);
    out.tt += truth.cwiseProduct(truth);
    out.mm += fit.cwiseProduct(fit);
  }
  return out;
}

// Relative RMS of the map at texel (s, t) against the truth at p over `directions`; NaN when the truth is black.
double relative_rms(const fitting::ParameterMap& map, int s, int t, const sim::Scene& scene, const Vec3d& p,
                    const std::vector<Vec3d>& directions) {
  double err2 = 0.0, truth2 = 0.0;
  for (const Vec3d& v : directions) {
    const Vec3d truth = scene.radiance(p, v);
    err2 += (map.evaluate(s, t, v) - truth).squaredNorm();
    truth2 += truth.squaredNorm();
  }
  return truth2 > 0.0 ? std::sqrt(err2 / truth2) : std::numeric_limits<double>::quiet_NaN();
}

// The scene material under the whole texel footprint, kMixed when it changes, kOutside off the surface.
float texel_material(const sim::Scene& scene, const Vec3d& centre, double half_w, double half_h) {
  const int m = scene.material_at(centre.x(), centre.y());
  if (m < 0) return kOutside;
  constexpr int kProbes = 5;  // a 5 x 5 grid over the footprint
  for (int j = 0; j < kProbes; ++j)
    for (int i = 0; i < kProbes; ++i) {
      const double x = centre.x() + half_w * (2.0 * i / (kProbes - 1) - 1.0) * 0.999;
      const double y = centre.y() + half_h * (2.0 * j / (kProbes - 1) - 1.0) * 0.999;
      if (scene.material_at(x, y) != m) return kMixed;
    }
  return static_cast<float>(m);
}

RelativeRmsStats stats(std::vector<double> values) {
  RelativeRmsStats out;
  if (values.empty()) return out;
  std::sort(values.begin(), values.end());
  double sum = 0.0;
  for (double v : values) sum += v;
  out.mean = sum / static_cast<double>(values.size());
  auto percentile = [&](double q) {
    const auto k = static_cast<size_t>(std::ceil(q * static_cast<double>(values.size()))) - 1;
    return values[std::min(k, values.size() - 1)];
  };
  out.p95 = percentile(0.95);
  out.p99 = percentile(0.99);
  out.max = values.back();
  return out;
}

// Camera centres (surface frame) of the session's views, from the first frame's measured pan/tilt of each complete
// view and the simulated rig's geometry (the nominal geometry for a hardware rig).
Result<std::vector<Vec3d>> session_camera_centres(const std::filesystem::path& dir) {
  auto session = capture::Session::open(dir);
  if (!session) return session.error();
  auto truth = ground_truth_of(session->manifest().rig_config);
  if (!truth) return truth.error();
  const rig::RigGeometry geometry = truth->has_value() ? (*truth)->geometry : rig::RigGeometry{};
  std::vector<Vec3d> centres;
  for (const auto& view : session->manifest().views) {
    if (!session->view_complete(view.index)) continue;
    const auto frames = session->frames_of_view(view.index);
    if (frames.empty()) continue;
    centres.push_back(rig::surface_pose(geometry, frames.front().measured).camera_centre());
  }
  if (centres.empty())
    return make_error(ErrorCode::kInvalidArgument, "session " + dir.string() + " has no complete view");
  return centres;
}

// The name of the simulated scene session `dir` was captured from; empty when the session cannot be opened, is not
// simulated, or its scene cannot be made (nothing to compare then).
std::string session_scene_name(const std::filesystem::path& dir) {
  std::error_code ec;
  if (dir.empty() || !std::filesystem::is_directory(dir, ec)) return "";
  auto session = capture::Session::open(dir);
  if (!session) return "";
  const auto scene = simulated_scene_of(session->manifest().rig_config);
  return scene ? scene->name : "";
}

// A warning for each session (the map's source session, the one asked for) captured from another scene than `scene`.
std::vector<std::string> scene_mismatch_warnings(const fitting::ParameterMap& map, const sim::Scene& scene,
                                                 const std::filesystem::path& session_dir) {
  std::vector<std::pair<std::string, std::filesystem::path>> sessions;
  const auto& attributes = map.image().string_attributes;
  if (const auto it = attributes.find("vdrig.source_session"); it != attributes.end() && !it->second.empty())
    sessions.push_back({"the map was fitted from", it->second});
  if (!session_dir.empty()) sessions.push_back({"--session", session_dir});
  std::vector<std::string> warnings;
  for (const auto& [what, dir] : sessions) {
    const std::string captured = session_scene_name(dir);
    if (captured.empty() || captured == scene.name) continue;
    warnings.push_back(what + " " + dir.string() + ", a capture of scene \"" + captured +
                       "\", but is evaluated against scene \"" + scene.name +
                       "\": the errors measure the difference between the scenes, not the fit");
  }
  return warnings;
}

}  // namespace

std::vector<Vec3d> hemisphere_directions(int n) {
  std::vector<Vec3d> out;
  out.reserve(static_cast<size_t>(std::max(n, 0)));
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (i + 0.5) / n;  // uniform in z: uniform in solid angle
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    out.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return out;
}

double texel_relative_rms(const fitting::ParameterMap& map, int s, int t, const sim::Scene& scene,
                          const std::vector<Vec3d>& directions) {
  const Vec3d p = texel_centre_mm(s, t, map.texels_s(), map.texels_t(), map.width_mm(), map.height_mm());
  return relative_rms(map, s, t, scene, p, directions);
}

Result<EvalReport> evaluate_map(const fitting::ParameterMap& map, const sim::Scene& scene, const EvalOptions& options) {
  if (options.dense_directions < 1)
    return make_error(ErrorCode::kInvalidArgument, "eval needs at least one dense direction");
  if (std::abs(map.width_mm() - scene.width_mm) > 1e-6 || std::abs(map.height_mm() - scene.height_mm) > 1e-6)
    return make_error(ErrorCode::kInvalidArgument, "the map covers " + std::to_string(map.width_mm()) + " x " +
                                                       std::to_string(map.height_mm()) + " mm but scene " + scene.name +
                                                       " is " + std::to_string(scene.width_mm) + " x " +
                                                       std::to_string(scene.height_mm) + " mm");
  std::vector<Vec3d> camera_centres;
  if (!options.session_dir.empty()) {
    auto centres = session_camera_centres(options.session_dir);
    if (!centres) return centres.error();
    camera_centres = std::move(centres.value());
  }
  const bool with_session = !camera_centres.empty();
  // Compared with a Phong-form truth where the model says what its diffuse part is (its lobes may be none).
  const fitting::ReflectanceModel& model = map.model();
  const bool phong_comparable = model.has_diffuse_part();
  const int S = map.texels_s(), T = map.texels_t();
  const double half_w = map.width_mm() / S / 2.0, half_h = map.height_mm() / T / 2.0;
  const std::vector<Vec3d> dense = hemisphere_directions(options.dense_directions);

  cv::Mat material(T, S, CV_32F);
  std::vector<ChannelSums> dense_sums(static_cast<size_t>(S) * T), session_sums(static_cast<size_t>(S) * T);
  // The Phong parameters of a texel, fitted and true, kept until the scale is known.
  struct PhongTexel {
    Vec3d kd_fit = Vec3d::Zero(), kd_true = Vec3d::Zero(), ks_fit = Vec3d::Zero(), ks_true = Vec3d::Zero();
    double m = 0;
    bool has_lobe = false, valid = false;
  };
  std::vector<PhongTexel> phong(static_cast<size_t>(S) * T);
  std::atomic<long> texels_done{0};
  std::mutex progress_mutex;
  const long texels_total = static_cast<long>(S) * T;
  cv::parallel_for_(cv::Range(0, T), [&](const cv::Range& rows) {
    std::vector<Vec3d> sampled;
    for (int t = rows.start; t < rows.end; ++t) {
      for (int s = 0; s < S; ++s) {
        const size_t i = static_cast<size_t>(t) * S + s;
        const Vec3d p = texel_centre_mm(s, t, S, T, map.width_mm(), map.height_mm());
        material.at<float>(t, s) = texel_material(scene, p, half_w, half_h);
        dense_sums[i] = channel_sums(map, s, t, scene, p, dense);
        if (with_session) {
          sampled.clear();
          for (const Vec3d& c : camera_centres)
            if (c.z() > p.z()) sampled.push_back((c - p).normalized());
          session_sums[i] = channel_sums(map, s, t, scene, p, sampled);
        }
        if (!phong_comparable) continue;
        const auto truth = scene.phong_truth(p);
        if (!truth || truth->kd.isZero()) continue;
        const std::vector<double> parameters = map.parameters(s, t);
        PhongTexel& out = phong[i];
        out.valid = true;
        out.kd_fit = model.diffuse_part(parameters);
        out.kd_true = truth->kd;
        if (!truth->ks.isZero()) {
          out.has_lobe = true;
          out.ks_true = truth->ks;
          const std::vector<fitting::LobeSummary> lobes = model.lobes(parameters);
          const fitting::LobeSummary* best = nullptr;
          for (const auto& lobe : lobes)
            if (!best || lobe.peak_rgb.sum() > best->peak_rgb.sum()) best = &lobe;
          // No lobe at all: Ks counts as entirely wrong (relative error 1), whatever the scale.
          out.ks_fit = best ? best->peak_rgb : Vec3d::Zero();
          out.m = best ? std::abs(best->phong_exponent - truth->shininess) / truth->shininess : 1.0;
        }
      }
      if (options.on_progress) {
        const long done = texels_done += S;
        std::lock_guard lock(progress_mutex);
        options.on_progress(done, texels_total);
      }
    }
  });

  // The scale per channel: the median over the materials of each material's median texel ratio map / truth (each
  // texel's least-squares ratio over the dense directions). A material votes once, so one large material the model
  // fits badly (a printed texture, a bumped metal) does not set the units of all the others.
  const auto median = [](std::vector<double> v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  Vec3d scale = Vec3d::Constant(std::numeric_limits<double>::quiet_NaN());
  for (int c = 0; c < 3; ++c) {
    std::vector<double> per_material;
    for (size_t m = 0; m < scene.materials.size(); ++m) {
      std::vector<double> ratios;
      for (int t = 0; t < T; ++t)
        for (int s = 0; s < S; ++s) {
          const ChannelSums& sums = dense_sums[static_cast<size_t>(t) * S + s];
          if (material.at<float>(t, s) == static_cast<float>(m) && sums.tt[c] > 0.0)
            ratios.push_back(sums.mt[c] / sums.tt[c]);
        }
      if (!ratios.empty()) per_material.push_back(median(std::move(ratios)));
    }
    scale[c] = median(std::move(per_material));
  }
  // A channel without a usable ratio (black in the truth everywhere, or a map that is zero) is left unscaled.
  const Vec3d k = scale.unaryExpr([](double x) { return std::isfinite(x) && x > 0.0 ? x : 1.0; });

  cv::Mat rel(T, S, CV_32F), rel_scaled(T, S, CV_32F), rel_session(T, S, CV_32F);
  for (int t = 0; t < T; ++t)
    for (int s = 0; s < S; ++s) {
      const size_t i = static_cast<size_t>(t) * S + s;
      rel.at<float>(t, s) = static_cast<float>(dense_sums[i].relative_rms());
      rel_scaled.at<float>(t, s) = static_cast<float>(dense_sums[i].relative_rms(k));
      if (with_session) rel_session.at<float>(t, s) = static_cast<float>(session_sums[i].relative_rms());
    }

  EvalReport report;
  report.model = map.model().name();
  report.dense_directions = options.dense_directions;
  report.session_views = static_cast<int>(camera_centres.size());
  report.scale = scale;
  report.warnings = scene_mismatch_warnings(map, scene, options.session_dir);
  report.error_map.add("rel_rms", rel);
  report.error_map.add("rel_rms.scaled", rel_scaled);
  if (with_session) report.error_map.add("rel_rms.session", rel_session);
  report.error_map.add("material", material);
  report.error_map.string_attributes["vdrig.eval_scene"] = scene.name;
  report.error_map.string_attributes["vdrig.eval_model"] = report.model;
  const auto relative = [](const Vec3d& fit, const Vec3d& truth) { return (fit - truth).norm() / truth.norm(); };
  for (size_t m = 0; m < scene.materials.size(); ++m) {
    std::vector<double> dense_values, dense_scaled, session_values, session_scaled;
    PhongParameterErrors sum, sum_scaled;
    int n_phong = 0, n_lobe = 0, texels = 0;
    for (int t = 0; t < T; ++t)
      for (int s = 0; s < S; ++s) {
        if (material.at<float>(t, s) != static_cast<float>(m)) continue;
        ++texels;
        const size_t i = static_cast<size_t>(t) * S + s;
        if (std::isfinite(rel.at<float>(t, s))) {
          dense_values.push_back(rel.at<float>(t, s));
          dense_scaled.push_back(rel_scaled.at<float>(t, s));
        }
        if (with_session && std::isfinite(rel_session.at<float>(t, s))) {
          session_values.push_back(rel_session.at<float>(t, s));
          session_scaled.push_back(session_sums[i].relative_rms(k));
        }
        const PhongTexel& pt = phong[i];
        if (!pt.valid) continue;
        ++n_phong;
        sum.kd_rel += relative(pt.kd_fit, pt.kd_true);
        sum_scaled.kd_rel += relative(pt.kd_fit.cwiseQuotient(k), pt.kd_true);
        if (!pt.has_lobe) continue;
        ++n_lobe;
        sum.ks_rel += relative(pt.ks_fit, pt.ks_true);
        sum_scaled.ks_rel += relative(pt.ks_fit.cwiseQuotient(k), pt.ks_true);
        sum.shininess_rel += pt.m;
        sum_scaled.shininess_rel += pt.m;
      }
    if (texels == 0) continue;
    MaterialEval e;
    e.name = scene.materials[m].name;
    e.texels = texels;
    e.dense = stats(dense_values);
    e.dense_scaled = stats(dense_scaled);
    e.has_session = with_session;
    if (with_session) e.session = stats(session_values), e.session_scaled = stats(session_scaled);
    if (n_phong > 0) {
      const double nan = std::numeric_limits<double>::quiet_NaN();
      const auto mean = [&](const PhongParameterErrors& x) {
        return PhongParameterErrors{x.kd_rel / n_phong, n_lobe ? x.ks_rel / n_lobe : nan,
                                    n_lobe ? x.shininess_rel / n_lobe : nan};
      };
      e.has_phong = true;
      e.phong = mean(sum);
      e.phong_scaled = mean(sum_scaled);
    }
    report.materials.push_back(e);
  }
  return report;
}

nlohmann::json EvalReport::to_json() const {
  auto number = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  nlohmann::json rows = nlohmann::json::array();
  for (const MaterialEval& m : materials) {
    nlohmann::json row = {{"material", m.name},
                          {"texels", m.texels},
                          {"rel_rms_mean", number(m.dense.mean)},
                          {"rel_rms_p95", number(m.dense.p95)},
                          {"rel_rms_p99", number(m.dense.p99)},
                          {"rel_rms_max", number(m.dense.max)}};
    if (m.has_session) {
      row["session_rel_rms_mean"] = number(m.session.mean);
      row["session_rel_rms_p95"] = number(m.session.p95);
      row["session_rel_rms_p99"] = number(m.session.p99);
      row["session_rel_rms_max"] = number(m.session.max);
    }
    if (m.has_phong) {
      row["kd_rel_error"] = number(m.phong.kd_rel);
      row["ks_rel_error"] = number(m.phong.ks_rel);
      row["shininess_rel_error"] = number(m.phong.shininess_rel);
    }
    // After the scale (EvalReport::scale): the figures a calibration from images can be judged by.
    row["scaled_rel_rms_mean"] = number(m.dense_scaled.mean);
    row["scaled_rel_rms_p95"] = number(m.dense_scaled.p95);
    row["scaled_rel_rms_p99"] = number(m.dense_scaled.p99);
    row["scaled_rel_rms_max"] = number(m.dense_scaled.max);
    if (m.has_session) {
      row["scaled_session_rel_rms_mean"] = number(m.session_scaled.mean);
      row["scaled_session_rel_rms_p95"] = number(m.session_scaled.p95);
    }
    if (m.has_phong) {
      row["scaled_kd_rel_error"] = number(m.phong_scaled.kd_rel);
      row["scaled_ks_rel_error"] = number(m.phong_scaled.ks_rel);
    }
    rows.push_back(row);
  }
  return {{"model", model},
          {"dense_directions", dense_directions},
          {"session_views", session_views},
          {"scale", {number(scale[0]), number(scale[1]), number(scale[2])}},
          {"materials", rows},
          {"warnings", warnings}};
}

std::string EvalReport::table() const {
  // Every column is separated by at least one space whatever its value: an error of 1471 (147100 %) once ran into the
  // texel count before it ("1100147113.78").
  auto pct = [](double x) {
    char buf[32];
    if (std::isfinite(x))
      std::snprintf(buf, sizeof buf, " %9.2f", 100.0 * x);
    else
      std::snprintf(buf, sizeof buf, " %9s", "-");
    return std::string(buf);
  };
  const bool session = session_views > 0;
  bool phong = false;
  for (const auto& m : materials) phong = phong || m.has_phong;
  std::string out = "model " + model + ", relative RMS in % over " + std::to_string(dense_directions) + " directions" +
                    (session ? " and the session's " + std::to_string(session_views) + " views" : "") + "\n";
  char line[256];
  std::snprintf(line, sizeof line,
                "scale map/truth (R G B) %.4f %.4f %.4f: units a response recovered from images cannot know;\n"
                "the sc. columns divide the map by it (a wrong shape or colour still shows there)\n",
                scale[0], scale[1], scale[2]);
  out += line;
  std::snprintf(line, sizeof line, "%-20s %7s %9s %9s %9s %9s", "material", "texels", "mean", "p95", "p99", "max");
  out += line;
  if (session) std::snprintf(line, sizeof line, "  %9s %9s", "sess.mean", "sess.p95"), out += line;
  if (phong) std::snprintf(line, sizeof line, "  %9s %9s %9s", "Kd err", "Ks err", "m err"), out += line;
  std::snprintf(line, sizeof line, "  %9s %9s", "sc.mean", "sc.p95"), out += line;
  if (session) std::snprintf(line, sizeof line, " %9s", "sc.sess"), out += line;
  if (phong) std::snprintf(line, sizeof line, " %9s %9s", "sc.Kd", "sc.Ks"), out += line;
  out += "\n";
  for (const MaterialEval& m : materials) {
    std::snprintf(line, sizeof line, "%-20.20s %7d", m.name.c_str(), m.texels);
    out += line + pct(m.dense.mean) + pct(m.dense.p95) + pct(m.dense.p99) + pct(m.dense.max);
    if (session) out += " " + pct(m.session.mean) + pct(m.session.p95);
    if (phong) {
      if (m.has_phong)
        out += " " + pct(m.phong.kd_rel) + pct(m.phong.ks_rel) + pct(m.phong.shininess_rel);
      else
        out += " " + pct(NAN) + pct(NAN) + pct(NAN);
    }
    out += " " + pct(m.dense_scaled.mean) + pct(m.dense_scaled.p95);
    if (session) out += pct(m.session_scaled.mean);
    if (phong) out += pct(m.has_phong ? m.phong_scaled.kd_rel : NAN) + pct(m.has_phong ? m.phong_scaled.ks_rel : NAN);
    out += "\n";
  }
  return out;
}

}  // namespace vdrig::pipeline

#include "vdrig/pipeline/fit_stage.hpp"

#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <vector>

#include "vdrig/capture/adaptive.hpp"
#include "vdrig/capture/session_layout.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/fitting/tiled_fit.hpp"
#include "vdrig/pipeline/compare_stage.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/pipeline/obsmap_stage.hpp"
#include "vdrig/pipeline/session_light.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

double default_smoothing(const fitting::ReflectanceModel& model) {
  return model.family() == "sh-ls" || model.family() == "hsh" ? 1e-4 : 0.0;
}

namespace {

constexpr const char* kEstimateLight = "estimate";  // `--light estimate`

/// The models' own options from the request (each model reads its own: fit_map.hpp, MapFitOptions::model_options).
/// An option the user gave must change what the model's fit reads, i.e. its options_fingerprint, or it does not apply
/// to the model and is refused rather than silently ignored: `--residual relative` on an SH, HSH or PTM fit (their
/// texels share one unweighted linear operator; only Phong weighs residuals), `--lobe-support` on a model without
/// lobes, `--smoothing` on PTM.
Status set_model_options(const FitRequest& r, fitting::MapFitOptions* options) {
  auto& phong = options->model_options.edit<fitting::PhongFitOptions>();
  phong.residual = r.residual == "relative" ? fitting::ResidualMode::kRelative : fitting::ResidualMode::kAbsolute;
  phong.lobe_support = r.lobe_support;
  phong.significant_lobes_only = !r.all_lobes;
  phong.solid_angle_weights = r.weights == "solid-angle";
  // SH/HSH regularisation: both option sets get it, the model's own validation rejects what does not apply.
  const double smoothing = r.smoothing.value_or(default_smoothing(*options->model));
  const fitting::RingingWindow window = r.window == "hanning"   ? fitting::RingingWindow::kHanning
                                        : r.window == "lanczos" ? fitting::RingingWindow::kLanczos
                                                                : fitting::RingingWindow::kNone;
  auto& sh = options->model_options.edit<fitting::ShFitOptions>();
  auto& hsh = options->model_options.edit<fitting::HshFitOptions>();
  sh.smoothing = hsh.smoothing = smoothing;
  sh.window = hsh.window = window;

  // Whether the model reads an option: does its fingerprint change when the option does?
  auto applies = [&](const std::function<void(fitting::MapFitOptions&)>& change) {
    fitting::MapFitOptions other = *options;
    change(other);
    return fitting::fit_options_fingerprint(other) != fitting::fit_options_fingerprint(*options);
  };
  auto refuse = [&](const std::string& flag) {
    return make_error(ErrorCode::kInvalidArgument, flag + " does not apply to " + options->model->family() + " models");
  };
  if (r.residual != "absolute" && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::PhongFitOptions>().residual = fitting::ResidualMode::kAbsolute;
      }))
    return refuse("--residual");
  if (r.lobe_support != fitting::PhongFitOptions{}.lobe_support &&
      !applies([](fitting::MapFitOptions& o) { ++o.model_options.edit<fitting::PhongFitOptions>().lobe_support; }))
    return refuse("--lobe-support");
  if (r.all_lobes && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::PhongFitOptions>().significant_lobes_only = true;
      }))
    return refuse("--all-lobes");
  if (r.weights == "solid-angle" && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::PhongFitOptions>().solid_angle_weights = false;
      }))
    return refuse("--weights solid-angle");
  if (r.smoothing.value_or(0.0) != 0.0 && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::ShFitOptions>().smoothing += 1.0;
        o.model_options.edit<fitting::HshFitOptions>().smoothing += 1.0;
      }))
    return refuse("--smoothing");
  // The session light (BRDF models): from the command line or the simulated scene; `--light estimate` and the
  // session's recorded light are resolved by the fit stage, which has the session (resolve_session_light).
  if (!r.light.empty() && !r.light_scene.empty())
    return make_error(ErrorCode::kInvalidArgument, "--light and --light-scene: give one of the two");
  if (r.light == kEstimateLight) {
    if (!applies([](fitting::MapFitOptions& o) { o.model_options.edit<fitting::GgxFitOptions>().light.emplace(); }))
      return refuse("--light");
  } else if (!r.light.empty() || !r.light_scene.empty()) {
    Result<fitting::SessionLight> light = make_error(ErrorCode::kInvalidArgument, "no light");
    if (!r.light.empty()) {
      light = parse_session_light(r.light);
    } else {
      auto scene = sim::make_scene(r.light_scene);
      if (!scene) return scene.error();
      light = session_light_of(scene.value());
    }
    if (!light) return light.error();
    options->model_options.edit<fitting::GgxFitOptions>().light = light.value();
    if (!applies([](fitting::MapFitOptions& o) { o.model_options.edit<fitting::GgxFitOptions>().light.reset(); }))
      return refuse(r.light.empty() ? "--light-scene" : "--light");
  }
  if (window != fitting::RingingWindow::kNone && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::ShFitOptions>().window = fitting::RingingWindow::kNone;
        o.model_options.edit<fitting::HshFitOptions>().window = fitting::RingingWindow::kNone;
      }))
    return refuse("--window");
  return Status::ok();
}

}  // namespace

Result<fitting::SessionLight> parse_session_light(const std::string& text) {
  std::vector<double> values;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, comma - start);
    char* end = nullptr;
    const double v = item.empty() ? 0.0 : std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(v))
      return make_error(ErrorCode::kInvalidArgument, "--light \"" + text + "\": \"" + item + "\" is not a number");
    values.push_back(v);
    start = comma + 1;
  }
  if (values.size() != 3 && values.size() != 4)
    return make_error(ErrorCode::kInvalidArgument,
                      "--light \"" + text + "\": expected X,Y,Z or X,Y,Z,I (surface frame, metres)");
  fitting::SessionLight light;
  light.position_m = Vec3d(values[0], values[1], values[2]);
  if (values.size() == 4) light.intensity = Vec3d::Constant(values[3]);
  if (const std::string why = light.check(); !why.empty())
    return make_error(ErrorCode::kInvalidArgument, "--light \"" + text + "\": " + why);
  return light;
}

Result<fitting::SessionLight> session_light_of(const sim::Scene& scene) {
  if (scene.lights.size() != 1 || !scene.area_lights.empty() || scene.ambient.maxCoeff() > 0)
    return make_error(ErrorCode::kInvalidArgument, "scene " + scene.name +
                                                       " is not lit by exactly one point light (a BRDF fit takes "
                                                       "one point light)");
  fitting::SessionLight light;
  light.position_m = scene.lights.front().position_mm / 1000.0;
  light.intensity = scene.lights.front().intensity * 1e-6;  // I / d_mm^2 = (I 1e-6) / d_m^2
  return light;
}

Result<fitting::MapFitOptions> fit_options_for(const FitRequest& r, int session_views,
                                               const std::vector<bool>& unusable, const std::string& scheme) {
  auto model = fitting::parse_model(r.model);
  if (!model) return model.error();
  if (r.residual != "absolute" && r.residual != "relative")
    return make_error(ErrorCode::kInvalidArgument, "--residual must be absolute or relative");
  if (r.window != "none" && r.window != "hanning" && r.window != "lanczos")
    return make_error(ErrorCode::kInvalidArgument, "--window must be none, hanning or lanczos");
  if (r.weights != "auto" && r.weights != "none" && r.weights != "solid-angle")
    return make_error(ErrorCode::kInvalidArgument, "--weights must be auto, none or solid-angle");
  if (r.threads < 0 || r.threads > fitting::MapFitOptions::kMaxThreads)
    return make_error(ErrorCode::kInvalidArgument, "--threads must be in [0, " +
                                                       std::to_string(fitting::MapFitOptions::kMaxThreads) +
                                                       "] (0: all cores), got " + std::to_string(r.threads));
  if (r.holdout < 0 || r.holdout >= session_views)
    return make_error(ErrorCode::kInvalidArgument,
                      "--holdout must be in [0, " + std::to_string(session_views - 1) + "]");
  fitting::MapFitOptions options;
  options.model = model.value();
  options.threads = r.threads;
  options.shared_lights = r.shared_lights;
  VDRIG_TRY(set_model_options(r, &options));
  // An adaptive session's views are dense where its planner put them (highlights): a plain least-squares fit would
  // weigh those directions more than the hemisphere's average error does (docs/sampling.md, "adaptive").
  if (r.weights == "auto" && capture::is_adaptive_scheme(scheme))
    options.model_options.edit<fitting::PhongFitOptions>().solid_angle_weights = true;
  // Held-out views spread over the session (never the normal view 0), as `vdrig demo` picks them. The observation
  // map holds every view so that the fit can measure the model on the held-out ones (holdout.R/G/B) while leaving
  // them out of the fit itself.
  // Only among the views the fit gets: a held-out view the calibration excluded would test nothing (`vdrig inspect`
  // then reported 1 of 3 held out).
  options.held_out = spread_holdout_views(session_views, r.holdout, unusable);
  if (static_cast<int>(options.held_out.size()) < r.holdout) {
    int usable = 0;
    for (int v = 1; v < session_views; ++v) usable += static_cast<size_t>(v) < unusable.size() && unusable[v] ? 0 : 1;
    return make_error(ErrorCode::kInvalidArgument, "--holdout " + std::to_string(r.holdout) + ": only " +
                                                       std::to_string(usable) +
                                                       " usable views besides view 0 (the others are excluded by the "
                                                       "calibration or incomplete)");
  }
  return options;
}

Status check_fit_output_writable(const fs::path& out) {
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec)
    return make_error(ErrorCode::kInvalidArgument, "--out: cannot create folder " + dir.string() + ": " + ec.message());
  if (fs::is_directory(out)) return make_error(ErrorCode::kInvalidArgument, "--out: " + out.string() + " is a folder");
  std::string probe = (dir / ".vdrig-write-check-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0)
    return make_error(ErrorCode::kInvalidArgument,
                      "--out: cannot write in " + dir.string() + ": " + std::strerror(errno));
  ::close(fd);
  ::unlink(probe.c_str());
  return Status::ok();
}

size_t map_bytes_at_most(const fitting::ReflectanceModel& model, int texels_s, int texels_t) {
  const size_t parameters = model.storable() ? model.channels().size() : std::max<size_t>(model.channels().size(), 32);
  return (parameters + 7 + 3 + 2) * static_cast<size_t>(texels_s) * static_cast<size_t>(texels_t) * sizeof(float);
}

Status check_map_fits(const fitting::ReflectanceModel& model, int texels_s, int texels_t, const fs::path& out) {
  const size_t bytes = map_bytes_at_most(model, texels_s, texels_t);
  auto mib = [](size_t b) { return std::to_string(b >> 20) + " MiB"; };
  if (bytes > fitting::ParameterMap::kMaxReadBytes)
    return make_error(ErrorCode::kInvalidArgument,
                      "--res " + std::to_string(texels_s) + "x" + std::to_string(texels_t) + ": a " + model.name() +
                          " map would take " + mib(bytes) + ", above the " + mib(fitting::ParameterMap::kMaxReadBytes) +
                          " that vdrig render/view can read back; choose a smaller --res");
  struct statvfs fs_stat {};
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  if (::statvfs(dir.c_str(), &fs_stat) == 0) {
    const size_t free_bytes = static_cast<size_t>(fs_stat.f_bavail) * fs_stat.f_frsize;
    if (free_bytes < bytes)
      return make_error(ErrorCode::kNoSpace, "--out " + out.string() + ": the map may take up to " + mib(bytes) +
                                                 " and " + dir.string() + " has " + mib(free_bytes) + " free");
  }
  return Status::ok();
}

FitSummary summarize_fit(const fitting::ParameterMap& map) {
  auto median_of = [&](const std::string& prefix) {
    std::vector<float> v;
    for (int t = 0; t < map.texels_t(); ++t)
      for (int s = 0; s < map.texels_s(); ++s)
        if (map.at("n", s, t) > 0)
          v.push_back((map.at(prefix + "R", s, t) + map.at(prefix + "G", s, t) + map.at(prefix + "B", s, t)) / 3.0f);
    if (v.empty()) return 0.0f;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  FitSummary summary;
  summary.median_rms = median_of("rms.");
  if (map.has("holdout.R")) summary.median_holdout_rms = median_of("holdout.");
  return summary;
}

std::string FitStageOptions::validate() const {
  if (session.empty()) return "no session folder";
  if (obsmap.empty() && (texels_s <= 0 || texels_t <= 0))
    return "--res " + std::to_string(texels_s) + "x" + std::to_string(texels_t) + ": texels must be positive";
  if (request.holdout < 0) return "--holdout must not be negative";
  if (!ranks.lead && !ranks.fit) return "a rank other than the lead needs the job's fit (FitStageRanks::fit)";
  return "";
}

namespace {

/// Whether the model reads a session light (its fingerprint changes with one: the BRDF models).
bool model_reads_light(const fitting::MapFitOptions& options) {
  fitting::MapFitOptions with = options, without = options;
  with.model_options.edit<fitting::GgxFitOptions>().light.emplace();
  without.model_options.edit<fitting::GgxFitOptions>().light.reset();
  return fitting::fit_options_fingerprint(with) != fitting::fit_options_fingerprint(without);
}

/// The light of a BRDF fit, in priority order: --light X,Y,Z[,I] or --light-scene (set by fit_options_for), --light
/// estimate (from the observations), the session's recorded lamp (its rig config, rig/lamp.hpp); refused naming the
/// three when there is none. nullopt for a view-only model, and for --light estimate while `obs` is null: called
/// before the observation map is made (a fit refused for want of a light is refused before that work) and after it.
Result<std::optional<ResolvedSessionLight>> resolve_session_light(const FitRequest& r, const capture::Session& session,
                                                                  const fitting::ObsMapReader* obs,
                                                                  fitting::MapFitOptions* options) {
  if (!model_reads_light(*options)) return std::optional<ResolvedSessionLight>();
  if (r.light == kEstimateLight && !obs) return std::optional<ResolvedSessionLight>();
  auto& ggx = options->model_options.edit<fitting::GgxFitOptions>();
  ResolvedSessionLight out;
  if (ggx.light) {
    out.light = *ggx.light;
    out.source = r.light.empty() ? "--light-scene " + r.light_scene + " (the simulated scene's point light)"
                                 : "--light " + r.light;
  } else if (r.light == kEstimateLight) {
    auto estimate = estimate_session_light(*obs, options->held_out, options->threads);
    if (!estimate) return estimate.error();
    out.light = estimate->session_light;
    out.source = "estimated from the images (phong:1 lobes, shared-lights pass): " + estimate->describe() +
                 "; intensity 1 at the sample's centre (gauge)";
  } else {
    auto recorded = recorded_session_light(session);
    if (!recorded) return recorded.error();
    if (!recorded.value())
      return make_error(ErrorCode::kInvalidArgument,
                        options->model->name() +
                            " is a BRDF: its fit needs the session's light, and this session recorded none (its rig "
                            "config's \"light\" has no \"position_mm\"); give --light X,Y,Z[,I] (surface frame, "
                            "metres), --light estimate (from the highlights), or --light-scene SCENE (a simulated "
                            "session)");
    out = std::move(*recorded.value());
  }
  ggx.light = out.light;
  out.source += " -> " + out.light.describe();
  return std::optional<ResolvedSessionLight>(std::move(out));
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

Result<FitStageResult> run_fit_steps(const FitStageOptions& o) {
  const std::string invalid = o.validate();
  if (!invalid.empty()) return make_error(ErrorCode::kInvalidArgument, invalid);
  const auto step = [&o](FitStep s, const std::string& line) {
    if (o.on_step && o.ranks.lead) o.on_step(s, line);
  };
  auto session = capture::Session::open(o.session);
  if (!session) return session.error();
  const int n_views = static_cast<int>(session->manifest().views.size());
  // Views whose observations the fit does not get: held-out views are chosen among the others.
  std::vector<bool> unusable(static_cast<size_t>(n_views), false);
  for (int v = 0; v < n_views; ++v) unusable[v] = !session->view_complete(v);
  if (auto geometry = session_geometry(session.value()); geometry)
    for (size_t v = 0; v < geometry->excluded.size() && v < unusable.size(); ++v)
      unusable[v] = unusable[v] || geometry->excluded[v];
  auto fit_options = fit_options_for(o.request, n_views, unusable, session->manifest().scheme);
  if (!fit_options) return fit_options.error();
  fitting::MapFitOptions& options = fit_options.value();
  const bool lead = o.ranks.lead;
  const fs::path out = o.out.empty() ? session->layout().parameter_map_file(options.model->name()) : o.out;
  // The default output is a file of the session (maps/): never reached through a link planted in the session.
  if (o.out.empty()) VDRIG_TRY(check_no_symlinks_below(session->dir(), out));
  if (lead) VDRIG_TRY(check_fit_output_writable(out));
  if (lead && o.obsmap.empty()) VDRIG_TRY(check_map_fits(*options.model, o.texels_s, o.texels_t, out));
  // Every rank resolves the light (the same on each: the estimate is deterministic), which its part of the fit reads;
  // all but the estimate now, before the observation map.
  auto light = resolve_session_light(o.request, session.value(), nullptr, &options);
  if (!light) return light.error();

  // The observation map streams through a file (SESSION/obsmap/<S>x<T>.vdobs, reused while current) and is fitted a
  // tile at a time, so memory stays bounded whatever the resolution.
  fs::path obsmap_path = o.obsmap;
  if (obsmap_path.empty() && !lead) {
    obsmap_path = session->layout().obsmap_file(o.texels_s, o.texels_t);
  } else if (obsmap_path.empty()) {
    step(FitStep::kObsMap, "observation map " + std::to_string(o.texels_s) + "x" + std::to_string(o.texels_t) +
                               " from " + std::to_string(n_views) + " views (" +
                               std::to_string(options.held_out.size()) + " held out)");
    ObsMapBuildOptions build;
    build.on_view = o.on_view;
    auto built = session_obsmap_file(session.value(), o.texels_s, o.texels_t, build);
    if (!built) return built.error();
    obsmap_path = built.value();
  }
  // The other ranks open the observation map once the lead has made it current (built on the lead alone here;
  // `vdrig obsmap build --mpi` builds it on every rank).
  if (o.ranks.barrier) VDRIG_TRY(o.ranks.barrier());
  auto obs = fitting::ObsMapReader::open(obsmap_path);
  if (!obs) return obs.error();
  if (obs->views() != n_views)
    return make_error(ErrorCode::kInvalidArgument, obsmap_path.string() + " holds " + std::to_string(obs->views()) +
                                                       " views, the session " + std::to_string(n_views));
  step(FitStep::kObservations, "observations from " + obsmap_path.string() + " (" +
                                   std::to_string(obs->spec().texels_s) + "x" + std::to_string(obs->spec().texels_t) +
                                   " texels)");

  if (o.request.light == kEstimateLight) {
    light = resolve_session_light(o.request, session.value(), &obs.value(), &options);
    if (!light) return light.error();
  }
  if (light.value()) step(FitStep::kObservations, "light: " + light.value()->source);

  step(FitStep::kFit, "fit " + options.model->name() + o.ranks.description);
  FitStageResult result;
  result.obsmap_file = obsmap_path;
  result.held_out = options.held_out;
  result.model = options.model->name();
  const auto fit_start = std::chrono::steady_clock::now();
  std::optional<fitting::ParameterMap> map;
  if (o.ranks.fit) {
    auto fitted = o.ranks.fit(obs.value(), options);
    if (!fitted) return fitted.error();
    map = std::move(fitted.value());
  } else {
    options.on_progress = o.on_progress;
    auto fitted = fitting::fit_parameter_map(obs.value(), options);
    if (!fitted) return fitted.error();
    map = std::move(fitted.value());
  }
  result.fit_seconds = seconds_since(fit_start);
  if (!lead || !map) return result;
  map->set_source_session(fs::absolute(o.session).string());
  if (!o.command.empty()) map->image().string_attributes["vdrig.command"] = o.command;
  if (light.value()) map->image().string_attributes["vdrig.session_light_source"] = light.value()->source;
  map->image().number_attributes[fitting::kFitSecondsAttribute] = result.fit_seconds;
  VDRIG_TRY(map->write(out));
  if (o.ranks.after_write) VDRIG_TRY(o.ranks.after_write(obs.value(), options));
  result.map_file = out;
  result.texels_s = map->texels_s();
  result.texels_t = map->texels_t();
  result.summary = summarize_fit(map.value());
  return result;
}

}  // namespace

Result<FitStageResult> run_fit_stage(const FitStageOptions& options) {
  // maps/ and obsmap/ (and the folder of `out`) are made before the work, so that a fit that cannot write its output
  // fails early, and removed again when they were made for nothing.
  const capture::SessionLayout layout(options.session);
  std::vector<fs::path> folders = {layout.maps_dir(), layout.obsmap_dir()};
  if (!options.out.empty() && options.out.has_parent_path()) folders.push_back(options.out.parent_path());
  std::vector<fs::path> made;  // folders this fit may create: those absent before it
  std::error_code ec;
  for (const fs::path& folder : folders)
    if (!fs::exists(folder, ec)) made.push_back(folder);
  auto result = run_fit_steps(options);
  if (!result)
    for (const fs::path& folder : made)
      if (fs::is_directory(folder, ec) && fs::is_empty(folder, ec)) fs::remove(folder, ec);
  return result;
}

}  // namespace vdrig::pipeline

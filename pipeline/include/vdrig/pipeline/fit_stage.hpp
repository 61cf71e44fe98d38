// The fit stage (`vdrig fit`): what the command line asks for turned into fitting::MapFitOptions, the checks made
// before a fit that can take hours (the output can be written, the map can be read back, the disk can hold it), and
// the summary printed after it. The fit itself is fitting::fit_parameter_map (one process) or cluster::fit_distributed
// (MPI); the observation map it reads is session_obsmap_file's (obsmap_stage.hpp).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::pipeline {

/// A fit as `vdrig fit` takes it (docs/models.md has what each option does).
struct FitRequest {
  std::string model = "phong:1";      // a model specification (fitting::model_registry().syntax())
  int holdout = 0;                    // views held out of the fit, spread over the session (spread_holdout_views)
  std::string residual = "absolute";  // Phong: absolute | relative
  bool shared_lights = false;         // Phong: lights shared by all texels
  int lobe_support = fitting::PhongFitOptions{}.lobe_support;
  bool all_lobes = false;           // Phong: keep lobes the BIC does not support
  std::optional<double> smoothing;  // SH/HSH Laplacian penalty; unset: default_smoothing(model)
  std::string window = "none";      // SH-ZH/HSH ringing window: none | hanning | lanczos
  int threads = 0;                  // 0: all cores
  /// BRDF models (ggx): the session's point light, "X,Y,Z" or "X,Y,Z,I" (surface frame, metres; I relative, default
  /// 1), or the single point light of a simulated scene (a built-in name or FILE.json); at most one of the two.
  std::string light;
  std::string light_scene;
};

/// The session light of `text` ("X,Y,Z" or "X,Y,Z,I": surface frame, metres; I default 1); kInvalidArgument with the
/// reason.
Result<fitting::SessionLight> parse_session_light(const std::string& text);
/// The session light of a simulated scene: its one point light, position in metres and intensity rescaled so that
/// E = I cos / d^2 with d in metres gives the simulator's irradiance (sim/scene.hpp measures d in mm).
/// kInvalidArgument for a scene lit otherwise (several lights, an area light, ambient light).
Result<fitting::SessionLight> session_light_of(const sim::Scene& scene);

/// The Laplacian penalty of a basis fit when none is asked for: least-squares SH and HSH ring between the views
/// without it (sh-ls:6 on the demo session: 21.8 % dense against 10.0 % at the views on glossy plastic; with 1e-4,
/// 11.2 and 11.2; docs/models.md, "Between the samples"); the projection methods take none.
double default_smoothing(const fitting::ReflectanceModel& model);

/// The fit options of `request` for a session of `session_views` views (held-out views chosen by
/// spread_holdout_views). kInvalidArgument naming the option: an unknown model, residual or window, threads or
/// holdout out of range, an option the model does not read (--residual relative on SH/HSH/PTM, --smoothing on PTM,
/// --lobe-support on a model without lobes: "does not apply to").
/// `unusable` (per view, may be empty): views whose observations the fit does not get (excluded by the calibration,
/// incomplete); held-out views are chosen among the others, and too few of them for --holdout is kInvalidArgument.
Result<fitting::MapFitOptions> fit_options_for(const FitRequest& request, int session_views,
                                               const std::vector<bool>& unusable = {});

/// Fails unless a file can be created beside `out` (its folder is made when missing) and `out` is not a folder:
/// checked before the fit, which can take hours, rather than when the map is written.
Status check_fit_output_writable(const std::filesystem::path& out);

/// What the map of `model` at S x T texels takes as float channels, at most: the model's parameters, the quality
/// channels (rms, mpe, n), holdout and the Phong extras (m_capped, shared_lights). A model whose layout the fit
/// decides (phong:auto: up to 4 lobes) counts as 32 parameters.
size_t map_bytes_at_most(const fitting::ReflectanceModel& model, int texels_s, int texels_t);

/// Refuses, before a fit that can take hours, a map that vdrig could not read back (ParameterMap::kMaxReadBytes:
/// `render` and `view` refuse it; kInvalidArgument) or that the disk cannot hold (its uncompressed size, an upper
/// bound; kNoSpace).
Status check_map_fits(const fitting::ReflectanceModel& model, int texels_s, int texels_t,
                      const std::filesystem::path& out);

/// Median over the fitted texels (n > 0) of the fit's RMS (mean of R, G, B), and of the held-out RMS when the map
/// has it.
struct FitSummary {
  double median_rms = 0;
  std::optional<double> median_holdout_rms;
};
FitSummary summarize_fit(const fitting::ParameterMap& map);

}  // namespace vdrig::pipeline

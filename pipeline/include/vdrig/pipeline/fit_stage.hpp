// The fit stage (`vdrig fit`): what the command line asks for turned into fitting::MapFitOptions, the checks made
// before a fit that can take hours (the output can be written, the map can be read back, the disk can hold it), and
// the summary printed after it. The fit itself is fitting::fit_parameter_map (one process) or cluster::fit_distributed
// (MPI); the observation map it reads is session_obsmap_file's (obsmap_stage.hpp).
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
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
  /// Phong: auto (solid-angle weights for an adaptive session, none otherwise) | none | solid-angle
  /// (fitting::PhongFitOptions::solid_angle_weights; docs/sampling.md, "adaptive").
  std::string weights = "auto";
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
/// `scheme`: the session's sampling scheme; weights "auto" weighs a Phong fit by solid angle for `adaptive:` ones.
Result<fitting::MapFitOptions> fit_options_for(const FitRequest& request, int session_views,
                                               const std::vector<bool>& unusable = {}, const std::string& scheme = {});

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

/// The steps of run_fit_stage that a caller may announce (FitStageOptions::on_step).
enum class FitStep {
  kObsMap,        // the session's observation map is made current (built, or reused while current)
  kObservations,  // the observation map is open: its file and size
  kFit,           // the fit starts
};

/// The hooks of an MPI job (cluster/, docs/scale.md): the pipeline links no cluster (MPI ranks link fitting only,
/// docs/conventions.md), so `vdrig fit --mpi` passes cluster::fit_distributed through here. Unset: one process.
struct FitStageRanks {
  bool lead = true;                 // this rank builds the observation map, announces the steps and writes the map
  std::function<Status()> barrier;  // every rank waits there until the lead has made the observation map current
  /// Fits in place of fitting::fit_parameter_map; the map on the lead, none on the other ranks.
  std::function<Result<std::optional<fitting::ParameterMap>>(const fitting::ObsMapReader&,
                                                             const fitting::MapFitOptions&)>
      fit;
  std::function<Status(const fitting::ObsMapReader&, const fitting::MapFitOptions&)> after_write;  // e.g. cleanup
  std::string description;  // appended to the kFit line, e.g. " on 4 MPI ranks"
};

/// A whole fit of a session, as `vdrig fit` and `vdrig demo` run it (run_fit_stage).
struct FitStageOptions {
  std::filesystem::path session;  // the session folder (hdr/ merged, calib/ made)
  FitRequest request;
  int texels_s = 256, texels_t = 256;  // the map's size (--res), unless `obsmap` is given
  std::filesystem::path out;           // the map; empty: SESSION/maps/<model>.exr (no link below the session)
  std::filesystem::path obsmap;        // an observation-map file to fit instead of SESSION/obsmap/<S>x<T>.vdobs
  std::string command;                 // the command line recorded in the map (vdrig.command; `vdrig report`)
  /// What the caller shows; each may be empty. on_step's line is the step as `vdrig fit` prints it.
  std::function<void(FitStep step, const std::string& line)> on_step;
  std::function<void(int done, int total)> on_view;                 // observation-map build, per view
  std::function<void(const fitting::MapFitProgress&)> on_progress;  // the fit in one process
  FitStageRanks ranks;

  /// Empty when the options can run; otherwise the reason, naming the option (what needs the session — the model's
  /// options, --holdout against its views — is checked by run_fit_stage, fit_options_for).
  std::string validate() const;
};

/// What run_fit_stage did.
struct FitStageResult {
  std::filesystem::path map_file;     // written (on the lead rank; empty on the others)
  std::filesystem::path obsmap_file;  // the observation map fitted
  std::vector<int> held_out;          // the views left out of the fit (fit_options_for: none excluded, all complete)
  std::string model;                  // the model's name
  int texels_s = 0, texels_t = 0;
  FitSummary summary;      // of the written map
  double fit_seconds = 0;  // the fit alone (also in the map, fitting::kFitSecondsAttribute)
};

/// `vdrig fit`: the options validated (kInvalidArgument with the reason), the held-out views chosen among those
/// the fit gets (neither excluded by the calibration nor incomplete), the output checked before the work
/// (writable, readable back, room on disk), the observation map made current (reused while current:
/// session_obsmap_file) or `options.obsmap` read, the model fitted (one process, or `options.ranks`), the map
/// written with its session and command. On failure the folders it made for nothing (maps/, obsmap/, the folder of
/// `out`) are removed again when empty.
Result<FitStageResult> run_fit_stage(const FitStageOptions& options);

}  // namespace vdrig::pipeline

// vdrig fit: a session's observation map fitted with one reflectance model into a parameter map (OpenEXR).
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <optional>

#include <fmt/format.h>

#include "commands.hpp"
#include "mpi_job.hpp"
#include "progress.hpp"
#include "vdrig/capture/session_layout.hpp"
#include "vdrig/cluster/distributed_fit.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"

namespace vdrig::app {
namespace {
namespace fs = std::filesystem;

struct FitArgs {
  std::string session;
  std::string model = "phong:1";
  std::string resolution = "256x256";
  std::string out;
  int holdout = 0;
  std::string residual = "absolute";
  bool shared_lights = false;
  int lobe_support = fitting::PhongFitOptions{}.lobe_support;
  bool all_lobes = false;
  std::optional<double> smoothing;  // unset: default_smoothing(model)
  std::string window = "none";
  std::string obsmap;  // an observation-map file to fit instead of SESSION/obsmap/<res>.vdobs
  int threads = 0;
  std::string light, light_scene;  // BRDF models: the session's point light (pipeline::FitRequest)
  bool mpi = false;                // one rank of `mpirun -n N vdrig fit ... --mpi` (cluster/, docs/scale.md)
};

/// The command line that asks for this fit (recorded in the map, shown by `vdrig report`).
std::string fit_command(const FitArgs& a) {
  std::string cmd = "vdrig fit " + a.session + " --model " + a.model;
  cmd += a.obsmap.empty() ? " --res " + a.resolution : " --obsmap " + a.obsmap;
  if (!a.out.empty()) cmd += " --out " + a.out;
  if (a.holdout > 0) cmd += " --holdout " + std::to_string(a.holdout);
  if (a.residual != "absolute") cmd += " --residual " + a.residual;
  if (a.shared_lights) cmd += " --shared-lights";
  if (a.lobe_support != fitting::PhongFitOptions{}.lobe_support)
    cmd += " --lobe-support " + std::to_string(a.lobe_support);
  if (a.all_lobes) cmd += " --all-lobes";
  if (!a.light.empty()) cmd += " --light " + a.light;
  if (!a.light_scene.empty()) cmd += " --light-scene " + a.light_scene;
  if (a.mpi) cmd += " --mpi";
  if (a.smoothing) cmd += " --smoothing " + fmt::format("{:g}", *a.smoothing);
  if (a.window != "none") cmd += " --window " + a.window;
  return cmd;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

pipeline::FitRequest fit_request(const FitArgs& a) {
  pipeline::FitRequest r;
  r.model = a.model;
  r.holdout = a.holdout;
  r.residual = a.residual;
  r.shared_lights = a.shared_lights;
  r.lobe_support = a.lobe_support;
  r.all_lobes = a.all_lobes;
  r.smoothing = a.smoothing;
  r.window = a.window;
  r.threads = a.threads;
  r.light = a.light;
  r.light_scene = a.light_scene;
  return r;
}

Status run_fit_steps(const FitArgs& a) {
  auto res = parse_resolution(a.resolution);
  if (!res) return res.error();
  auto session = capture::Session::open(a.session);
  if (!session) return session.error();
  const int n_views = static_cast<int>(session->manifest().views.size());
  // Views whose observations the fit does not get: held-out views are chosen among the others.
  std::vector<bool> unusable(static_cast<size_t>(n_views), false);
  for (int v = 0; v < n_views; ++v) unusable[v] = !session->view_complete(v);
  if (auto geometry = pipeline::session_geometry(session.value()); geometry)
    for (size_t v = 0; v < geometry->excluded.size() && v < unusable.size(); ++v)
      unusable[v] = unusable[v] || geometry->excluded[v];
  auto fit_options = pipeline::fit_options_for(fit_request(a), n_views, unusable);
  if (!fit_options) return fit_options.error();
  fitting::MapFitOptions& options = fit_options.value();
  const fs::path out = a.out.empty() ? session->layout().parameter_map_file(options.model->name()) : fs::path(a.out);
  cluster::Comm* comm = nullptr;
  if (a.mpi) {
    auto world = cluster::world();
    if (!world) return world.error();
    comm = world.value();
  }
  const bool lead = !comm || comm->rank() == 0;  // the rank that prints, builds the observation map, writes the map
  // The default output is a file of the session (maps/): never reached through a link planted in the session.
  if (a.out.empty()) VDRIG_TRY(check_no_symlinks_below(session->dir(), out));
  if (lead) VDRIG_TRY(pipeline::check_fit_output_writable(out));
  if (lead && a.obsmap.empty()) VDRIG_TRY(pipeline::check_map_fits(*options.model, res->first, res->second, out));

  // The observation map streams through a file (SESSION/obsmap/<S>x<T>.vdobs, reused while current) and is fitted a
  // tile at a time, so memory stays bounded whatever --res is.
  std::filesystem::path obsmap_path = a.obsmap;
  if (obsmap_path.empty() && !lead) {
    obsmap_path = session->layout().obsmap_file(res->first, res->second);
  } else if (obsmap_path.empty()) {
    std::printf("observation map %dx%d from %d views (%zu held out)\n", res->first, res->second, n_views,
                options.held_out.size());
    pipeline::ObsMapBuildOptions build;
    ProgressLine progress;
    build.on_view = [&progress](int done, int total) { progress.update(done, total, "  views %d/%d", done, total); };
    auto built = pipeline::session_obsmap_file(session.value(), res->first, res->second, build);
    progress.finish();
    if (!built) return built.error();
    obsmap_path = built.value();
  }
  // The other ranks open the observation map once rank 0 has made it current (built on rank 0 alone here; `vdrig
  // obsmap build --mpi` builds it on every rank).
  if (comm) VDRIG_TRY(comm->barrier());
  auto obs = fitting::ObsMapReader::open(obsmap_path);
  if (!obs) return obs.error();
  if (obs->views() != n_views)
    return make_error(ErrorCode::kInvalidArgument, obsmap_path.string() + " holds " + std::to_string(obs->views()) +
                                                       " views, the session " + std::to_string(n_views));
  if (lead)
    std::printf("observations from %s (%dx%d texels)\n", obsmap_path.c_str(), obs->spec().texels_s,
                obs->spec().texels_t);

  if (comm) {
    if (lead) std::printf("fit %s on %d MPI ranks\n", options.model->name().c_str(), comm->size());
    cluster::DistributedFitOptions distributed;
    distributed.tiles_root = out.string() + ".tiles";
    ProgressLine tile_progress;
    distributed.on_tile = [&tile_progress](int pass, int done, int total) {
      tile_progress.update(done, total, "  pass %d: tiles %d/%d", pass + 1, done, total);
    };
    // TEST HOOK (tests/cluster): rank VDRIG_TEST_MPI_EXIT_RANK exits hard after VDRIG_TEST_MPI_EXIT_AFTER_TILES
    // recorded tiles, to test that a lost rank ends the job and that the job resumes.
    if (const char* r = std::getenv("VDRIG_TEST_MPI_EXIT_RANK"); r && std::atoi(r) == comm->rank())
      if (const char* n = std::getenv("VDRIG_TEST_MPI_EXIT_AFTER_TILES"))
        distributed.test_exit_after_tiles = std::atoi(n);
    const auto fit_start = std::chrono::steady_clock::now();
    auto fitted = cluster::fit_distributed(*comm, obs.value(), options, distributed);
    tile_progress.finish();
    if (!fitted) return fitted.error();
    if (!lead) return Status::ok();
    fitting::ParameterMap& map = fitted->value();
    map.set_source_session(fs::absolute(a.session).string());
    map.image().string_attributes["vdrig.command"] = fit_command(a);
    map.image().number_attributes[fitting::kFitSecondsAttribute] = seconds_since(fit_start);
    VDRIG_TRY(map.write(out));
    // The map is durable (written atomically): its tile records are no longer needed.
    auto store =
        cluster::TileStore::open(distributed.tiles_root, cluster::fit_fingerprint(obs.value(), options), false);
    if (store) VDRIG_TRY(store->remove());
    std::printf("wrote %s (%s, %dx%d texels)\n", out.c_str(), map.model().name().c_str(), map.texels_s(),
                map.texels_t());
    return Status::ok();
  }

  std::printf("fit %s\n", options.model->name().c_str());
  ProgressLine fit_progress;
  options.on_progress = [&fit_progress](const fitting::MapFitProgress& p) {
    fit_progress.update(p.texels_done, p.texels_total, "  texels %d/%d (%.0f %%), %.0f s elapsed, ETA %.0f s",
                        p.texels_done, p.texels_total, 100.0 * p.texels_done / std::max(1, p.texels_total), p.elapsed_s,
                        p.eta_s);
  };
  const auto fit_start = std::chrono::steady_clock::now();
  auto map = fitting::fit_parameter_map(obs.value(), options);
  fit_progress.finish();
  if (!map) return map.error();
  map->set_source_session(fs::absolute(a.session).string());
  map->image().string_attributes["vdrig.command"] = fit_command(a);
  map->image().number_attributes[fitting::kFitSecondsAttribute] = seconds_since(fit_start);
  VDRIG_TRY(map->write(out));

  const pipeline::FitSummary summary = pipeline::summarize_fit(map.value());
  std::printf("wrote %s (%s, %dx%d texels); median RMS %.4g", out.c_str(), map->model().name().c_str(), map->texels_s(),
              map->texels_t(), summary.median_rms);
  if (summary.median_holdout_rms) std::printf(", median held-out RMS %.4g", *summary.median_holdout_rms);
  std::printf("\n");
  return Status::ok();
}

/// The fit, leaving no empty folder behind when it fails: maps/ and obsmap/ (and --out's folder) are made before the
/// work, so that a fit that cannot write its output fails early, and removed again when they were made for nothing.
Status run_fit(const FitArgs& a) {
  const capture::SessionLayout layout(a.session);
  std::vector<fs::path> folders = {layout.maps_dir(), layout.obsmap_dir()};
  if (!a.out.empty() && fs::path(a.out).has_parent_path()) folders.push_back(fs::path(a.out).parent_path());
  std::vector<fs::path> made;  // folders this fit may create: those absent before it
  std::error_code ec;
  for (const fs::path& folder : folders)
    if (!fs::exists(folder, ec)) made.push_back(folder);
  const Status status = run_fit_steps(a);
  if (!status)
    for (const fs::path& folder : made)
      if (fs::is_directory(folder, ec) && fs::is_empty(folder, ec)) fs::remove(folder, ec);
  return status;
}

const CommandRegistrar kFit([](CLI::App& root) {
  auto args = std::make_shared<FitArgs>();
  auto* cmd = root.add_subcommand("fit", "Fit a reflectance model to every texel of a session -> parameter map (EXR)");
  cmd->add_option("session", args->session, "session folder (with hdr/ merged)")->required();
  cmd->add_option("--model", args->model, fitting::model_registry().syntax())->capture_default_str();
  cmd->add_option("--res", args->resolution, "parameter map resolution, SxT texels")->capture_default_str();
  cmd->add_option("--out", args->out, "output EXR (default SESSION/maps/<model>.exr)");
  cmd->add_option("--holdout", args->holdout, "views held out of the fit; the map gets their RMS (holdout.R/G/B)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--residual", args->residual, "Phong residual: absolute | relative")
      ->capture_default_str()
      ->check(CLI::IsMember({"absolute", "relative"}));
  cmd->add_flag("--shared-lights", args->shared_lights,
                "Phong: estimate the rig's lights from all texels and refit each texel's lobes toward them (sparse "
                "view sets; the map gets a shared_lights channel)");
  cmd->add_option("--lobe-support", args->lobe_support,
                  "Phong: observations each lobe needs inside its support cone (>= 10 % of its peak); narrower lobes "
                  "have their shininess capped to the sampling (0: no cap; docs/models.md, \"Between the samples\")")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  cmd->add_flag("--all-lobes", args->all_lobes,
                "Phong: keep every lobe of phong:K (and at least one of phong:auto) even where it does not lower the "
                "BIC; by default a texel gets only the lobes its observations identify");
  cmd->add_option("--smoothing", args->smoothing,
                  "SH/HSH: Laplacian penalty lambda (default 1e-4 for sh-ls and hsh, which ring between the views "
                  "without it, 0 for the others; docs/models.md)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--window", args->window, "SH-ZH/HSH: ringing window after the fit: none | hanning | lanczos")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "hanning", "lanczos"}));
  cmd->add_option(
      "--light", args->light,
      "BRDF models (ggx): the session's point light X,Y,Z[,I] (surface frame, metres; I relative, default 1)");
  cmd->add_option("--light-scene", args->light_scene,
                  "BRDF models (ggx): take the light from the simulated scene the session was captured from");
  cmd->add_option("--obsmap", args->obsmap, "fit this observation-map file (vdrig obsmap build) instead of --res")
      ->check(CLI::ExistingFile);
  cmd->add_option("--threads", args->threads,
                  "worker threads (0 = all cores; at most " + std::to_string(fitting::MapFitOptions::kMaxThreads) + ")")
      ->capture_default_str();
  cmd->add_flag("--mpi", args->mpi,
                "one rank of an MPI job (mpirun -n N vdrig fit ... --mpi): tiles handed out by rank 0, each recorded "
                "in OUT.tiles/ so that a killed job resumes (docs/scale.md)");
  cmd->callback([args] { finish_job(run_fit(*args)); });
});

}  // namespace
}  // namespace vdrig::app

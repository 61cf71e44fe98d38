// vdrig fit: a session's observation map fitted with one reflectance model into a parameter map (OpenEXR).
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <optional>
#include <tuple>

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
  std::string weights = "auto";    // Phong: auto | none | solid-angle (pipeline::FitRequest)
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
  if (a.weights != "auto") cmd += " --weights " + a.weights;
  if (a.mpi) cmd += " --mpi";
  if (a.smoothing) cmd += " --smoothing " + fmt::format("{:g}", *a.smoothing);
  if (a.window != "none") cmd += " --window " + a.window;
  return cmd;
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
  r.weights = a.weights;
  return r;
}

/// The fit is pipeline::run_fit_stage's (fit_stage.hpp); this command parses, shows progress and, with --mpi, hands
/// the stage cluster's distributed fit (the pipeline links no cluster).
Status run_fit(const FitArgs& a) {
  pipeline::FitStageOptions stage;
  stage.session = a.session;
  stage.request = fit_request(a);
  stage.out = a.out;
  stage.obsmap = a.obsmap;
  stage.command = fit_command(a);
  if (a.obsmap.empty()) {
    auto res = parse_resolution(a.resolution);
    if (!res) return res.error();
    std::tie(stage.texels_s, stage.texels_t) = res.value();
  }
  ProgressLine view_progress, fit_progress, tile_progress;
  stage.on_view = [&view_progress](int done, int total) {
    view_progress.update(done, total, "  views %d/%d", done, total);
  };
  stage.on_step = [&view_progress](pipeline::FitStep, const std::string& line) {
    view_progress.finish();
    std::printf("%s\n", line.c_str());
  };
  stage.on_progress = [&fit_progress](const fitting::MapFitProgress& p) {
    fit_progress.update(p.texels_done, p.texels_total, "  texels %d/%d (%.0f %%), %.0f s elapsed, ETA %.0f s",
                        p.texels_done, p.texels_total, 100.0 * p.texels_done / std::max(1, p.texels_total), p.elapsed_s,
                        p.eta_s);
  };
  cluster::DistributedFitOptions distributed;
  if (a.mpi) {
    auto world = cluster::world();
    if (!world) return world.error();
    cluster::Comm* comm = world.value();
    stage.ranks.lead = comm->rank() == 0;  // the rank that prints, builds the observation map, writes the map
    stage.ranks.description = " on " + std::to_string(comm->size()) + " MPI ranks";
    stage.ranks.barrier = [comm] { return comm->barrier(); };
    distributed.on_tile = [&tile_progress](int pass, int done, int total) {
      tile_progress.update(done, total, "  pass %d: tiles %d/%d", pass + 1, done, total);
    };
    // TEST HOOK (tests/cluster): rank VDRIG_TEST_MPI_EXIT_RANK exits hard after VDRIG_TEST_MPI_EXIT_AFTER_TILES
    // recorded tiles, to test that a lost rank ends the job and that the job resumes.
    if (const char* r = std::getenv("VDRIG_TEST_MPI_EXIT_RANK"); r && std::atoi(r) == comm->rank())
      if (const char* n = std::getenv("VDRIG_TEST_MPI_EXIT_AFTER_TILES"))
        distributed.test_exit_after_tiles = std::atoi(n);
    // Tile records beside the map (OUT.tiles/), where the stage puts the map: the model's default name or --out.
    const auto tiles_root = [&a](const fitting::MapFitOptions& options) {
      const fs::path out =
          a.out.empty() ? capture::SessionLayout(a.session).parameter_map_file(options.model->name()) : fs::path(a.out);
      return fs::path(out.string() + ".tiles");
    };
    stage.ranks.fit = [comm, &distributed, &tile_progress, tiles_root](const fitting::ObsMapReader& obs,
                                                                       const fitting::MapFitOptions& options) {
      distributed.tiles_root = tiles_root(options);
      auto fitted = cluster::fit_distributed(*comm, obs, options, distributed);
      tile_progress.finish();
      return fitted;
    };
    // The map is durable (written atomically): its tile records are no longer needed.
    stage.ranks.after_write = [&distributed](const fitting::ObsMapReader& obs, const fitting::MapFitOptions& options) {
      auto store = cluster::TileStore::open(distributed.tiles_root, cluster::fit_fingerprint(obs, options), false);
      return store ? store->remove() : Status::ok();
    };
  }
  auto fitted = pipeline::run_fit_stage(stage);
  fit_progress.finish();
  if (!fitted) return fitted.error();
  if (fitted->map_file.empty()) return Status::ok();  // a rank other than the lead
  std::printf("wrote %s (%s, %dx%d texels)", fitted->map_file.c_str(), fitted->model.c_str(), fitted->texels_s,
              fitted->texels_t);
  if (!a.mpi) {
    std::printf("; median RMS %.4g", fitted->summary.median_rms);
    if (fitted->summary.median_holdout_rms)
      std::printf(", median held-out RMS %.4g", *fitted->summary.median_holdout_rms);
  }
  std::printf("\n");
  return Status::ok();
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
      "BRDF models (ggx): the session's point light X,Y,Z[,I] (surface frame, metres; I relative, default 1), or "
      "\"estimate\" (from the highlights: the Phong lobes' shared-lights pass refined by ggx:iso); default: the "
      "light the session recorded (its rig config's lamp), refused when none");
  cmd->add_option("--light-scene", args->light_scene,
                  "BRDF models (ggx): take the light from the simulated scene the session was captured from");
  cmd->add_option("--weights", args->weights,
                  "Phong: observation weights, auto (by solid angle for an adaptive session) | none | solid-angle "
                  "(each view weighed by its share of the hemisphere; docs/sampling.md)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "none", "solid-angle"}));
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

// vdrig fit: a session's observation map fitted with one reflectance model into a parameter map (OpenEXR).
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
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
#include "vdrig/cluster/distributed_fit.hpp"
#include "vdrig/core/file_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/fitting/tiled_fit.hpp"
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
  bool mpi = false;  // one rank of `mpirun -n N vdrig fit ... --mpi` (cluster/, docs/scale.md)
};

/// Fails unless a file can be created beside `out` (its folder is made when missing) and `out` is not a folder:
/// checked before the fit, which can take hours, rather than when the map is written.
Status check_output_writable(const fs::path& out) {
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

/// What the map of `model` at S x T texels takes as float channels, at most: the model's parameters, the quality
/// channels (rms, mpe, n), holdout and the Phong extras (m_capped, shared_lights). A model whose layout the fit
/// decides (phong:auto: up to 4 lobes) counts as 32 parameters.
size_t map_bytes_at_most(const fitting::ReflectanceModel& model, int S, int T) {
  const size_t parameters = model.storable() ? model.channels().size() : std::max<size_t>(model.channels().size(), 32);
  return (parameters + 7 + 3 + 2) * static_cast<size_t>(S) * static_cast<size_t>(T) * sizeof(float);
}

/// Refuses, before a fit that can take hours, a map that vdrig could not read back (ParameterMap::kMaxReadBytes:
/// `render` and `view` refuse it) or that the disk cannot hold (its uncompressed size: an upper bound).
Status check_map_fits(const fitting::ReflectanceModel& model, int S, int T, const fs::path& out) {
  const size_t bytes = map_bytes_at_most(model, S, T);
  auto mib = [](size_t b) { return std::to_string(b >> 20) + " MiB"; };
  if (bytes > fitting::ParameterMap::kMaxReadBytes)
    return make_error(ErrorCode::kInvalidArgument, "--res " + std::to_string(S) + "x" + std::to_string(T) + ": a " +
                                                       model.name() + " map would take " + mib(bytes) + ", above the " +
                                                       mib(fitting::ParameterMap::kMaxReadBytes) +
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

/// The Laplacian penalty of a basis fit when --smoothing is not given: least-squares SH and HSH ring between the
/// views without it (sh-ls:6 on the demo session: 21.8 % dense against 10.0 % at the views on glossy plastic; with
/// 1e-4, 11.2 and 11.2; docs/models.md, "Between the samples"); the projection methods take none.
double default_smoothing(const fitting::ReflectanceModel& model) {
  return model.family() == "sh-ls" || model.family() == "hsh" ? 1e-4 : 0.0;
}

fitting::RingingWindow ringing_window(const std::string& name) {
  return name == "hanning"   ? fitting::RingingWindow::kHanning
         : name == "lanczos" ? fitting::RingingWindow::kLanczos
                             : fitting::RingingWindow::kNone;
}

/// The models' own options from the command line (each model reads its own: fit_map.hpp, MapFitOptions::model_options).
/// A flag the user gave must change what the model's fit reads, i.e. its options_fingerprint, or it does not apply to
/// the model and is refused rather than silently ignored: `--residual relative` on an SH, HSH or PTM fit (their
/// texels share one unweighted linear operator; only Phong weighs residuals), `--lobe-support` on a model without
/// lobes, `--smoothing` on PTM.
Status set_model_options(const FitArgs& a, fitting::MapFitOptions* options) {
  auto& phong = options->model_options.edit<fitting::PhongFitOptions>();
  phong.residual = a.residual == "relative" ? fitting::ResidualMode::kRelative : fitting::ResidualMode::kAbsolute;
  phong.lobe_support = a.lobe_support;
  phong.significant_lobes_only = !a.all_lobes;
  // SH/HSH regularisation: both option sets get it, the model's own validation rejects what does not apply.
  const double smoothing = a.smoothing.value_or(default_smoothing(*options->model));
  const fitting::RingingWindow window = ringing_window(a.window);
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
  if (a.residual != "absolute" && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::PhongFitOptions>().residual = fitting::ResidualMode::kAbsolute;
      }))
    return refuse("--residual");
  if (a.lobe_support != fitting::PhongFitOptions{}.lobe_support &&
      !applies([](fitting::MapFitOptions& o) { ++o.model_options.edit<fitting::PhongFitOptions>().lobe_support; }))
    return refuse("--lobe-support");
  if (a.all_lobes && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::PhongFitOptions>().significant_lobes_only = true;
      }))
    return refuse("--all-lobes");
  if (a.smoothing.value_or(0.0) != 0.0 && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::ShFitOptions>().smoothing += 1.0;
        o.model_options.edit<fitting::HshFitOptions>().smoothing += 1.0;
      }))
    return refuse("--smoothing");
  if (window != fitting::RingingWindow::kNone && !applies([](fitting::MapFitOptions& o) {
        o.model_options.edit<fitting::ShFitOptions>().window = fitting::RingingWindow::kNone;
        o.model_options.edit<fitting::HshFitOptions>().window = fitting::RingingWindow::kNone;
      }))
    return refuse("--window");
  return Status::ok();
}

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
  if (a.mpi) cmd += " --mpi";
  if (a.smoothing) cmd += " --smoothing " + fmt::format("{:g}", *a.smoothing);
  if (a.window != "none") cmd += " --window " + a.window;
  return cmd;
}

Status run_fit(const FitArgs& a) {
  auto model = fitting::parse_model(a.model);
  if (!model) return model.error();
  auto res = parse_resolution(a.resolution);
  if (!res) return res.error();
  if (a.residual != "absolute" && a.residual != "relative")
    return make_error(ErrorCode::kInvalidArgument, "--residual must be absolute or relative");
  if (a.threads < 0 || a.threads > fitting::MapFitOptions::kMaxThreads)
    return make_error(ErrorCode::kInvalidArgument, "--threads must be in [0, " +
                                                       std::to_string(fitting::MapFitOptions::kMaxThreads) +
                                                       "] (0: all cores), got " + std::to_string(a.threads));
  auto session = capture::Session::open(a.session);
  if (!session) return session.error();
  const int n_views = static_cast<int>(session->manifest().views.size());
  if (a.holdout < 0 || a.holdout >= n_views)
    return make_error(ErrorCode::kInvalidArgument, "--holdout must be in [0, " + std::to_string(n_views - 1) + "]");
  const fs::path out = a.out.empty() ? session->layout().parameter_map_file(model.value()->name()) : fs::path(a.out);
  cluster::Comm* comm = nullptr;
  if (a.mpi) {
    auto world = cluster::world();
    if (!world) return world.error();
    comm = world.value();
  }
  const bool lead = !comm || comm->rank() == 0;  // the rank that prints, builds the observation map, writes the map
  // The default output is a file of the session (maps/): never reached through a link planted in the session.
  if (a.out.empty()) VDRIG_TRY(check_no_symlinks_below(session->dir(), out));
  if (lead) VDRIG_TRY(check_output_writable(out));
  if (lead && a.obsmap.empty()) VDRIG_TRY(check_map_fits(*model.value(), res->first, res->second, out));

  // Held-out views spread over the session (never the normal view 0), as `vdrig demo` picks them. The observation
  // map holds every view so that the fit can measure the model on the held-out ones (holdout.R/G/B) while leaving
  // them out of the fit itself.
  fitting::MapFitOptions options;
  options.model = model.value();
  options.threads = a.threads;
  options.shared_lights = a.shared_lights;
  VDRIG_TRY(set_model_options(a, &options));
  options.held_out = pipeline::spread_holdout_views(n_views, a.holdout);

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
    auto fitted = cluster::fit_distributed(*comm, obs.value(), options, distributed);
    tile_progress.finish();
    if (!fitted) return fitted.error();
    if (!lead) return Status::ok();
    fitting::ParameterMap& map = fitted->value();
    map.set_source_session(fs::absolute(a.session).string());
    map.image().string_attributes["vdrig.command"] = fit_command(a);
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
  auto map = fitting::fit_parameter_map(obs.value(), options);
  fit_progress.finish();
  if (!map) return map.error();
  map->set_source_session(fs::absolute(a.session).string());
  map->image().string_attributes["vdrig.command"] = fit_command(a);
  VDRIG_TRY(map->write(out));

  // Summary: median RMS over texels with a fit (and held-out RMS when views were held out).
  auto median_of = [&](const char* prefix) {
    std::vector<float> v;
    for (int t = 0; t < map->texels_t(); ++t)
      for (int s = 0; s < map->texels_s(); ++s)
        if (map->at("n", s, t) > 0)
          v.push_back((map->at(std::string(prefix) + "R", s, t) + map->at(std::string(prefix) + "G", s, t) +
                       map->at(std::string(prefix) + "B", s, t)) /
                      3.0f);
    if (v.empty()) return 0.0f;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  std::printf("wrote %s (%s, %dx%d texels); median RMS %.4g", out.c_str(), map->model().name().c_str(), map->texels_s(),
              map->texels_t(), median_of("rms."));
  if (map->has("holdout.R")) std::printf(", median held-out RMS %.4g", median_of("holdout."));
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

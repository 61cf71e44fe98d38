// vdrig demo: the whole pipeline on the simulated rig, start to finish, writing images a person can look at. It
// calibrates as a real rig must (intrinsics from a chessboard session, the response curve from the brackets, the poses
// from the markers): nothing is taken from the simulator's configuration.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <tuple>

#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/capture/session_layout.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::app {
namespace {
namespace fs = std::filesystem;

struct DemoArgs {
  std::string out = "out/demo";
  std::string scene = "patchwork";
  std::string scheme = capture::kDefaultScheme;
  std::string chessboard_scheme = "latlong:4:65";  // the intrinsics target's views (fewer: a quicker, rougher camera)
  std::string resolution = "128x128";              // SxT texels, as `vdrig fit --res`
  int holdout = 3;                                 // views held out of the fit, as `vdrig fit --holdout`
};

constexpr const char* kDemoMark = "vdrig demo";  // manifest extra "created_by" of a session the demo made

/// The demo's intrinsics target: the built-in scene `chessboard` (9 x 7 squares of 160 mm: 8 x 6 inner corners),
/// seen from rings up to 65 degrees (DemoArgs::chessboard_scheme), two exposures (the longer one unsaturated on its
/// white squares).
constexpr int kChessboardCols = 8, kChessboardRows = 6;
constexpr double kChessboardSquareM = 0.160;

/// Makes room for the demo's session. Running the demo again replaces the session an earlier demo made, but never
/// deletes what vdrig did not create: a folder that is not a demo session (its manifest says who made it), or one
/// holding anything the demo does not write (a notes file, a map fitted by hand), is refused and left alone.
Status clear_earlier_demo(const fs::path& session_dir) {
  std::error_code ec;
  if (!fs::exists(session_dir, ec) || fs::is_empty(session_dir, ec)) return Status::ok();
  const auto refuse = [&](const std::string& why) {
    return make_error(ErrorCode::kInvalidArgument,
                      session_dir.string() + " is not empty and " + why + ": pick another --out or remove it yourself");
  };
  const capture::SessionLayout layout(session_dir);
  auto manifest = read_json_file(layout.manifest_file());
  if (!manifest || !manifest->contains("extra") || !(*manifest)["extra"].is_object() ||
      (*manifest)["extra"].value("created_by", "") != kDemoMark)
    return refuse("is not a session `vdrig demo` made");
  // What the demo writes, folder by folder (SessionLayout), and the file types in each.
  const std::map<fs::path, std::set<std::string>> demo_folders = {
      {layout.frames_dir(), {".png"}},   {layout.hdr_dir(), {".exr"}},  {layout.calib_dir(), {".json", ".yml"}},
      {layout.obsmap_dir(), {".vdobs"}}, {layout.maps_dir(), {".exr"}}, {layout.renders_dir(), {".png"}}};
  const std::set<fs::path> demo_files = {layout.manifest_file(), layout.journal_file(), layout.lock_file()};
  // What `vdrig compare` writes into the demo session by default: renders/compare/compare.json and a folder of PNGs
  // per map.
  const fs::path compare = layout.compare_dir();
  const auto compare_output = [&](const fs::path& path) {
    std::error_code ignored;
    if (path.parent_path() == compare) return path.extension() == ".json" || fs::is_directory(path, ignored);
    return path.parent_path().parent_path() == compare && path.extension() == ".png";
  };
  for (const auto& entry : fs::directory_iterator(session_dir, ec)) {
    if (demo_files.count(entry.path()) && entry.is_regular_file()) continue;
    const auto folder = demo_folders.find(entry.path());
    if (folder == demo_folders.end() || !entry.is_directory()) return refuse("holds " + entry.path().string());
    for (const auto& file : fs::recursive_directory_iterator(entry.path(), ec)) {
      if (file.is_regular_file() && file.path().parent_path() == entry.path() &&
          folder->second.count(file.path().extension().string()))
        continue;
      if (!compare_output(file.path()) && file.path() != compare) return refuse("holds " + file.path().string());
    }
  }
  if (ec) return make_error(ErrorCode::kIo, "cannot list " + session_dir.string() + ": " + ec.message());
  fs::remove_all(session_dir, ec);
  if (ec)
    return make_error(ErrorCode::kIo, "cannot remove the earlier demo " + session_dir.string() + ": " + ec.message());
  return Status::ok();
}

/// A session of the simulated rig showing `scene`, marked as the demo's (clear_earlier_demo may replace it), with
/// the views' progress on stdout: the chessboard session and the session of the scene are captured alike.
Result<capture::Session> capture_demo_session(const fs::path& dir, const std::string& scene, const std::string& scheme,
                                              std::vector<double> exposures_s) {
  pipeline::CaptureRequest req;
  req.out_dir = dir;
  req.manifest_extra = {{"created_by", kDemoMark}};
  req.rig_config = sim::sim_rig_config({{"scene", scene}});
  req.scheme = scheme;
  req.exposures_s = std::move(exposures_s);
  ProgressLine progress;
  req.on_view = [&progress](int done, int total) { progress.update(done, total, "    views %d/%d", done, total); };
  auto session = pipeline::capture_session(req);
  progress.finish();
  return session;
}

Status run_demo(const DemoArgs& a) {
  auto logger = log::get("app");
  const fs::path out = fs::absolute(a.out);
  const fs::path session_dir = out / "session";
  std::error_code ec;
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed_s = [&start] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  std::vector<std::pair<std::string, double>> steps;  // each step's wall time, seconds, printed at the end
  double step_start_s = 0.0;
  const auto end_step = [&](const std::string& name) {
    steps.push_back({name, elapsed_s() - step_start_s});
    step_start_s = elapsed_s();
  };
  // --res as `vdrig fit` takes it (SxT); a bare N, the demo's old form, still means NxN.
  std::string resolution = a.resolution;
  if (!resolution.empty() && resolution.find_first_not_of("0123456789") == std::string::npos) {
    log::get("app")->warn("--res {}: a bare number is deprecated, write {}x{} (SxT, as vdrig fit --res)", resolution,
                          resolution, resolution);
    resolution += "x" + resolution;
  }
  auto parsed_res = parse_resolution(resolution);
  if (!parsed_res) return parsed_res.error();
  const std::pair<int, int> res = parsed_res.value();
  const fs::path chessboard_dir = out / "chessboard";
  VDRIG_TRY(clear_earlier_demo(chessboard_dir));
  VDRIG_TRY(clear_earlier_demo(session_dir));
  constexpr int kSteps = 9;

  // Intrinsics as on a real rig: a session of a chessboard, calibrated from its images.
  std::printf("1/%d chessboard capture: scene chessboard, scheme %s -> %s\n", kSteps, a.chessboard_scheme.c_str(),
              chessboard_dir.c_str());
  auto board_session = capture_demo_session(chessboard_dir, "chessboard", a.chessboard_scheme, {1.0, 0.25});
  if (!board_session) return board_session.error();
  end_step("chessboard capture");

  const fs::path camera_file = board_session->layout().camera_file();
  std::printf("2/%d intrinsics from the chessboard views (%dx%d inner corners of %.0f mm, k3 fixed) -> %s\n", kSteps,
              kChessboardCols, kChessboardRows, kChessboardSquareM * 1000, camera_file.c_str());
  pipeline::SessionIntrinsicsOptions intrinsics_options;
  intrinsics_options.board_cols = kChessboardCols;
  intrinsics_options.board_rows = kChessboardRows;
  intrinsics_options.square_m = kChessboardSquareM;
  intrinsics_options.intrinsics.fix_k3 = true;
  auto intrinsics = pipeline::calibrate_session_intrinsics(board_session.value(), intrinsics_options);
  if (!intrinsics) return intrinsics.error();
  fs::create_directories(camera_file.parent_path(), ec);
  VDRIG_TRY(intrinsics->save_yaml(camera_file));
  const CameraModel& cam = intrinsics->camera;
  std::printf("    fx %.1f fy %.1f cx %.1f cy %.1f k1 %.3f k2 %.3f, RMS %.2f px over %zu views\n", cam.fx, cam.fy,
              cam.cx, cam.cy, cam.k1, cam.k2, intrinsics->rms_px, intrinsics->used_views());
  end_step("intrinsics");

  std::printf("3/%d capture: scene %s, scheme %s -> %s\n", kSteps, a.scene.c_str(), a.scheme.c_str(),
              session_dir.c_str());
  auto session = capture_demo_session(session_dir, a.scene, a.scheme, {1.0, 0.25, 0.0625});
  if (!session) return session.error();
  const int n_views = static_cast<int>(session->manifest().views.size());
  end_step("capture");

  const capture::SessionLayout layout = session->layout();
  std::printf("4/%d response curve from the brackets (Debevec-Malik) -> %s\n", kSteps, layout.response_file().c_str());
  auto response = pipeline::calibrate_session_response(session.value());
  if (!response) return response.error();
  std::printf("    bracket of view %d, %d codes covered\n", response->view, response->codes_covered);
  end_step("response");

  std::printf("5/%d HDR merge of %d brackets -> %s\n", kSteps, n_views, layout.hdr_dir().c_str());
  pipeline::HdrMergeOptions hdr_options;
  ProgressLine hdr_progress;
  hdr_options.on_view = [&hdr_progress](int done, int total) {
    hdr_progress.update(done, total, "    views %d/%d", done, total);
  };
  auto merged = pipeline::merge_session_hdr(session.value(), hdr_options);
  hdr_progress.finish();
  if (!merged) return merged.error();
  end_step("HDR");

  std::printf("6/%d extrinsics from the corner markers and the rig's kinematic fit -> %s\n", kSteps,
              layout.views_file().c_str());
  pipeline::GeometryCalibrationOptions geometry_options;
  geometry_options.camera = intrinsics->camera;
  auto geometry = pipeline::calibrate_session_geometry(session.value(), geometry_options);
  if (!geometry) return geometry.error();
  std::printf("    %d of %zu views posed by their markers, the others by the kinematic fit\n", geometry->usable_views,
              geometry->views.views.size());
  end_step("extrinsics");

  // The fit is `vdrig fit`'s (pipeline::run_fit_stage): held-out views spread over the session (never the normal
  // view 0) among the views the fit gets, to test it on unseen directions; the observation map holds every view
  // (streamed to SESSION/obsmap/); the fit leaves the held-out ones out and measures itself on them (holdout.R/G/B).
  if (a.holdout >= n_views)
    return make_error(ErrorCode::kInvalidArgument, "--holdout " + std::to_string(a.holdout) +
                                                       ": the session has only " + std::to_string(n_views) + " views");
  pipeline::FitStageOptions fit_stage;
  fit_stage.session = session_dir;
  fit_stage.request.model = "phong:1";
  fit_stage.request.holdout = a.holdout;
  std::tie(fit_stage.texels_s, fit_stage.texels_t) = res;
  fit_stage.command = "vdrig demo --out " + a.out + " --scene " + a.scene + " --scheme " + a.scheme + " --res " +
                      a.resolution + " --holdout " + std::to_string(a.holdout);
  ProgressLine view_progress, fit_progress;
  fit_stage.on_view = [&view_progress](int done, int total) {
    view_progress.update(done, total, "    views %d/%d", done, total);
  };
  fit_stage.on_step = [&](pipeline::FitStep step, const std::string& line) {
    view_progress.finish();
    if (step == pipeline::FitStep::kObsMap) std::printf("7/%d %s\n", kSteps, line.c_str());
    if (step != pipeline::FitStep::kFit) return;
    end_step("observation map");
    std::printf("8/%d %s per texel\n", kSteps, line.c_str());
  };
  fit_stage.on_progress = [&fit_progress](const fitting::MapFitProgress& p) {
    fit_progress.update(p.texels_done, p.texels_total, "    texels %d/%d, ETA %.0f s", p.texels_done, p.texels_total,
                        p.eta_s);
  };
  auto fitted = pipeline::run_fit_stage(fit_stage);
  fit_progress.finish();
  if (!fitted) return fitted.error();
  const std::vector<int>& held_out = fitted->held_out;
  const fs::path map_path = fitted->map_file;
  end_step("fit");

  std::printf("9/%d render the held-out views and compare them with the photographs (as vdrig compare)\n", kSteps);
  // The comparison is `vdrig compare SESSION --maps phong:1 --views held-out`'s own (pipeline::compare_maps: both
  // images tone mapped from HDR, |render - photo| over the surface pixels with exact radiance), written where that
  // command writes it, so the demo and compare print one figure for one view.
  pipeline::CompareOptions compare_options;
  compare_options.command =
      "vdrig demo (vdrig compare " + session_dir.string() + " --maps " + fitted->model + " --views held-out)";
  auto compared = pipeline::compare_maps(session.value(), {map_path}, held_out, compare_options);
  if (!compared) return compared.error();
  for (const pipeline::ViewComparison& row : compared->rows) {
    std::printf("    view %d: mean |render - photo| = %.2f (all), %.2f (diffuse), %.2f (highlight), 8-bit codes\n",
                row.view, row.all.mean, row.diffuse.mean, row.highlight.mean);
    std::printf("      %s\n      %s\n      %s\n", row.render_png.c_str(), row.photo_png.c_str(), row.diff_png.c_str());
  }
  end_step("compare");
  std::printf("\nparameter map: %s\nsession:       %s\nimages:        %s\n", map_path.c_str(), session_dir.c_str(),
              compared->json_file.parent_path().c_str());
  // Which calibration the figures rest on: every file made from the images, none from the simulator's truth.
  std::printf(
      "calibration (from the images, not the simulator's truth):\n  camera:   %s (chessboard, %zu views; copied to "
      "calib/ of the session)\n"
      "  response: %s (bracket of view %d)\n  poses:    %s (%d of %zu views by markers)\n",
      camera_file.c_str(), intrinsics->used_views(), layout.response_file().c_str(), response->view,
      layout.views_file().c_str(), geometry->usable_views, geometry->views.views.size());
  std::string breakdown;
  for (const auto& [name, seconds] : steps)
    breakdown += (breakdown.empty() ? "" : ", ") + name + " " + fmt::format("{:.1f}", seconds) + " s";
  std::printf("demo: %.1f s in all (%s)\n", elapsed_s(), breakdown.c_str());
  return Status::ok();
}

const CommandRegistrar kDemo([](CLI::App& root) {
  auto args = std::make_shared<DemoArgs>();
  auto* cmd =
      root.add_subcommand("demo",
                          "Simulated rig, calibrated from its images (chessboard intrinsics, response, markers) -> HDR "
                          "-> observation map -> Phong fit -> rendered images");
  cmd->add_option("--out", args->out, "output folder")->capture_default_str();
  cmd->add_option("--scene", args->scene, "simulated scene: a built-in name or a scene FILE.json")
      ->capture_default_str();
  cmd->add_option("--scheme", args->scheme, "sampling scheme (see docs/sampling.md)")->capture_default_str();
  cmd->add_option("--chessboard-scheme", args->chessboard_scheme,
                  "sampling scheme of the chessboard session the intrinsics come from")
      ->capture_default_str();
  cmd->add_option("--res", args->resolution, "parameter map resolution, SxT texels (as vdrig fit --res)")
      ->capture_default_str();
  cmd->add_option("--holdout", args->holdout,
                  "views held out of the fit (as vdrig fit --holdout), rendered and compared; at least 1")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->callback([args] { finish(run_demo(*args)); });
});

}  // namespace
}  // namespace vdrig::app

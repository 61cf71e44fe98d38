// vdrig capture: plan and run a capture session, or resume an interrupted one (the journal is the truth).
#include <cstdio>

#include "commands.hpp"
#include "progress.hpp"
#include "rig_backends.hpp"
#include "vdrig/capture/adaptive.hpp"
#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/process_lock.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/rig/lamp.hpp"

namespace vdrig::app {
namespace {
namespace fs = std::filesystem;

struct CaptureArgs {
  std::string rig = "sim";  // "sim" or a rig config JSON file
  std::string scene = "patchwork";
  std::string scheme = capture::kDefaultScheme;
  std::string bracket = "auto";
  std::string out;
  std::string resume;
  std::vector<int> redo_views;  // with --resume: complete views to shoot again
  std::string geometry;         // a calibration's views.json: its kinematic fit becomes the rig config's "geometry"
  std::string runtime_dir;      // ignored: locks no longer live in a runtime folder (process_lock.hpp)
  double reserve_mb = 256;
  capture::RetryPolicy retry;  // device faults: attempts in all and the backoff between them
};

Status run(const CaptureArgs& a) {
  auto registry = rig_backends();
  capture::CaptureOptions options;
  auto reserve = capture::disk_reserve_bytes_from_mib(a.reserve_mb);
  if (!reserve) return reserve.error();
  options.disk_reserve_bytes = reserve.value();
  options.retry = a.retry;
  if (a.retry.max_attempts < 1 || !(a.retry.initial_backoff_s >= 0) || !(a.retry.max_backoff_s >= 0))
    return make_error(ErrorCode::kInvalidArgument, "--device-attempts must be >= 1 and the backoffs >= 0");
  std::optional<capture::Session> session;
  // One process drives a rig: its devices lock themselves when it is built, a rig named by "lock" is locked here
  // (process_lock.hpp); held until the capture returns, taken before a session folder is made for it.
  std::optional<capture::ProcessLock> rig_lock;
  auto lock_rig = [&](const nlohmann::json& rig_config) -> Status {
    auto held = capture::lock_rig(rig_config);
    if (!held) return held.error();
    rig_lock = std::move(held.value());
    return Status::ok();
  };
  if (!a.resume.empty() && !a.geometry.empty())
    return make_error(ErrorCode::kInvalidArgument,
                      "--geometry plans a new session; a resumed one keeps the geometry its manifest records");
  if (!a.redo_views.empty() && a.resume.empty())
    return make_error(ErrorCode::kInvalidArgument, "--redo VIEWS re-shoots views of a session: give --resume DIR");
  if (!a.resume.empty()) {
    // Locked before the journal is read: another process capturing into it is refused with its PID.
    auto s = capture::Session::open_for_capture(a.resume);
    if (!s) return s.error();
    session = std::move(s.value());
    if (!a.redo_views.empty()) VDRIG_TRY(session->mark_views_incomplete(a.redo_views, "vdrig capture --redo"));
    std::printf("resuming %s: %d/%zu views complete\n", a.resume.c_str(), session->completed_view_count(),
                session->manifest().views.size());
  } else {
    if (a.out.empty()) return make_error(ErrorCode::kInvalidArgument, "--out DIR or --resume DIR is required");
    nlohmann::json rc;
    if (a.rig == "sim" || a.rig == "blender") {
      // --rig blender: the simulated stage with the Blender camera (docs/blender.md); a .blend scene is rendered
      // from the file, on a 1000 mm surface with the built-in scenes' corner markers.
      const bool blend = a.rig == "blender" && fs::path(a.scene).extension() == ".blend";
      auto simulated = simulated_rig_config(blend ? "patchwork" : a.scene);
      if (!simulated) return simulated.error();
      rc = std::move(simulated.value());
      if (a.rig == "blender") rc["camera"] = {{"backend", "blender"}};
      if (blend) rc["camera"]["blend"] = fs::absolute(a.scene).string();
      // The .blend's lights are its own, not patchwork's: no lamp recorded (a rig config with "position_mm" gives one).
      if (blend) rc["light"] = rig::without_lamp_keys(rc["light"]);
    } else {
      auto file = read_json_file(a.rig);
      if (!file) return make_error(ErrorCode::kInvalidArgument, "cannot read rig config: " + file.error().message);
      rc = std::move(file.value());
    }
    if (!a.geometry.empty()) {
      auto fitted = capture::with_fitted_geometry(rc, a.geometry);
      if (!fitted) return make_error(ErrorCode::kInvalidArgument, "--geometry: " + fitted.error().message);
      rc = std::move(fitted.value());
    }
    VDRIG_TRY(lock_rig(rc));
    auto rig = registry.make_rig(rc);
    if (!rig) return rig.error();
    capture::PlanRequest plan;
    plan.rig_config = rc;
    plan.scheme = a.scheme;
    plan.bracket = a.bracket;
    plan.stage = rig->stage->spec();
    auto surface = simulated_surface_size(rc);
    if (!surface) return surface.error();
    if (surface.value()) {
      plan.surface_width_mm = surface.value()->width_mm;
      plan.surface_height_mm = surface.value()->height_mm;
    }
    // Adaptive sampling needs its planner (a build with the pipeline): refused before anything is made.
    if (capture::is_adaptive_scheme(a.scheme)) VDRIG_TRY(capture::check_adaptive_capture(a.scheme, a.out, rc));
    auto manifest =
        capture::is_adaptive_scheme(a.scheme) ? capture::plan_adaptive_manifest(plan) : capture::plan_manifest(plan);
    if (!manifest) return manifest.error();
    const auto& route = manifest->extra["route"];
    std::printf("%zu views; moves %.1f s planned vs %.1f s in scheme order\n", manifest->views.size(),
                route["planned_time_s"].get<double>(), route["naive_time_s"].get<double>());
    auto s = capture::Session::create(a.out, manifest.value());
    if (!s) return s.error();
    session = std::move(s.value());
  }
  auto bracket = capture::parse_bracket(session->manifest().bracket);
  if (!bracket) return bracket.error();
  options.bracket = bracket.value();
  ProgressLine progress;
  options.on_progress = [&progress](const capture::CaptureProgress& p) {
    progress.update(p.views_done, p.views_total, "  views %d/%d  view %d frame %d (%.4g s)  ETA %.0f s", p.views_done,
                    p.views_total, p.view, p.bracket_index, p.exposure_s, p.eta_s);
  };
  VDRIG_TRY(session->lock());
  if (!a.resume.empty()) VDRIG_TRY(lock_rig(session->manifest().rig_config));
  auto rig = registry.make_rig(session->manifest().rig_config);
  if (!rig) return rig.error();
  Status s = Status::ok();
  if (session->manifest().extra.contains("adaptive")) {
    auto planner = capture::make_view_planner();
    if (!planner) return planner.error();
    capture::AdaptiveOptions adaptive;
    adaptive.capture = options;
    adaptive.on_batch = [&progress](const capture::AdaptiveProgress& p) {
      progress.finish();
      if (p.stopped) {
        std::printf("adaptive sampling stopped: %s\n", p.stopped->c_str());
      } else if (!p.batches.empty()) {
        const auto& b = p.batches.back();
        std::printf("batch %d: %zu views planned (%.1f s of moves), predicted held-out error %.4g\n", b.batch,
                    b.views.size(), b.move_s, b.predicted_error);
      }
    };
    s = capture::run_adaptive_session(rig.value(), session.value(), *planner.value(), adaptive);
  } else {
    s = capture::run_session(rig.value(), session.value(), options);
  }
  progress.finish();
  // Whatever stopped it (a full disk, a drive fault, a camera gone), the journal keeps every completed view.
  if (!s)
    std::printf("stopped after %d/%zu views; nothing is lost: vdrig capture --resume %s\n",
                session->completed_view_count(), session->manifest().views.size(), session->dir().c_str());
  return s;
}

CommandRegistrar reg([](CLI::App& root) {
  auto a = std::make_shared<CaptureArgs>();
  auto* cmd = root.add_subcommand("capture", "capture a session (or --resume an interrupted one)");
  cmd->add_option("--rig", a->rig, "'sim', 'blender' (the simulated stage, Cycles renders) or a rig config JSON file")
      ->capture_default_str();
  cmd->add_option("--scene", a->scene,
                  "simulator scene: a built-in name, a scene FILE.json, or with --rig blender a FILE.blend")
      ->capture_default_str();
  cmd->add_option("--scheme", a->scheme, "sampling scheme (docs/sampling.md)")->capture_default_str();
  cmd->add_option("--bracket", a->bracket, "fixed:E1,E2,... or auto[:CEIL[:FLOOR]][@X,Y,W,H]")->capture_default_str();
  cmd->add_option("--out", a->out, "new session folder");
  cmd->add_option("--resume", a->resume, "session folder to resume (rig config from its manifest)");
  cmd->add_option("--redo", a->redo_views,
                  "with --resume: views to shoot again although complete, e.g. 4,17 (journaled as view_redo)")
      ->delimiter(',');
  cmd->add_option("--geometry", a->geometry,
                  "aim with a calibrated rig: a views.json whose kinematic fit (vdrig calib extrinsics) replaces the "
                  "rig config's \"geometry\" (recorded in the manifest)");
  cmd->add_option("--reserve-mb", a->reserve_mb, "free disk space to keep, MiB")->capture_default_str();
  cmd->add_option("--device-attempts", a->retry.max_attempts,
                  "attempts of a device call (stage, camera) before the session stops with the fault")
      ->capture_default_str();
  cmd->add_option("--backoff-s", a->retry.initial_backoff_s, "wait before the first retry (doubles after each)")
      ->capture_default_str();
  cmd->add_option("--max-backoff-s", a->retry.max_backoff_s, "longest wait between retries")->capture_default_str();
  cmd->add_option("--runtime-dir", a->runtime_dir,
                  "ignored, for older scripts: rigs are locked per device wherever the runtime folder is");
  cmd->callback([a] { finish(run(*a)); });
});

}  // namespace
}  // namespace vdrig::app

// `vdrig view MAP.exr [--session S] [--constrained] [--gamma G] [--frames N --screenshot out.png]`: the interactive
// viewer (viewer/interactive.hpp, docs/viewer.md). With a session, the camera is the session's (calibrated, or the
// simulator's) and its captured views can be stepped through; without, a 1024x768 pinhole 2500 mm above the surface.
#include <cstdio>
#include <memory>
#include <string>

#include "commands.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/viewer/interactive.hpp"

namespace vdrig::app {
namespace {

struct ViewArgs {
  std::string map, session, screenshot, screenshot_dir = ".";
  bool constrained = false, hidden = false;
  int view = 0, frames = 0, samples = 2, max_window_px = 1280;
  double gamma = 1.0, distance_mm = 2500.0;
};

Status run_view(const ViewArgs& a) {
  auto map = fitting::ParameterMap::read(a.map);
  if (!map) return map.error();
  viewer::ViewerOptions o;
  if (!a.session.empty()) {
    auto session = capture::Session::open(a.session);
    if (!session) return session.error();
    auto geometry = pipeline::session_geometry(session.value());
    if (!geometry) return geometry.error();
    o.camera = geometry->camera;
    o.captured_views = geometry->poses;
    int excluded = 0;
    for (const bool e : geometry->excluded) excluded += e ? 1 : 0;
    log::get("app")->info("session {}: {} views ({} posed by the kinematic fit only), camera {}x{} ({})", a.session,
                          o.captured_views.size(), excluded, o.camera->width, o.camera->height, geometry->source);
  } else if (a.constrained) {
    return make_error(ErrorCode::kInvalidArgument, "--constrained needs --session (the captured views)");
  }
  o.constrained = a.constrained;
  o.initial_view = a.view;
  o.gamma = a.gamma;
  o.distance_mm = a.distance_mm;
  o.render.samples_per_axis = a.samples;
  o.max_window_px = a.max_window_px;
  o.max_frames = a.frames;
  o.visible = !a.hidden;
  o.last_frame_png = a.screenshot;
  o.screenshot_dir = a.screenshot_dir;
  auto result = viewer::run_viewer(map.value(), o);
  if (!result) return result.error();
  if (!a.screenshot.empty())
    std::printf("%d frames; last frame (%s, gamma %.3g) -> %s\n", result->frames,
                result->mode == viewer::ViewCamera::Mode::kConstrained
                    ? ("captured view " + std::to_string(result->view)).c_str()
                    : "free camera",
                result->gamma, a.screenshot.c_str());
  for (const auto& s : result->screenshots) std::printf("screenshot %s\n", s.c_str());
  return Status::ok();
}

const CommandRegistrar registrar([](CLI::App& root) {
  auto a = std::make_shared<ViewArgs>();
  auto* cmd = root.add_subcommand(
      "view",
      "interactive viewer of a parameter map (docs/viewer.md). Mouse: drag orbits (or steps between captured views), "
      "right drag pans, wheel zooms. Keys: C free/constrained, N/P next/previous view, +/- gamma, S screenshot, "
      "R reset, Esc/Q quit");
  cmd->add_option("map", a->map, "parameter map (OpenEXR, from vdrig fit)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--session", a->session, "session folder: its camera and captured view poses");
  cmd->add_flag("--constrained", a->constrained, "start at a captured view (needs --session)");
  cmd->add_option("--view", a->view, "captured view to start at (with --constrained)")->capture_default_str();
  cmd->add_option("--gamma", a->gamma, "tone mapping y = 1 - exp(-gamma x)")->capture_default_str();
  cmd->add_option("--distance", a->distance_mm, "free camera distance, mm")->capture_default_str();
  cmd->add_option("--samples", a->samples, "antialiasing sub-samples per pixel axis")->capture_default_str();
  cmd->add_option("--max-window", a->max_window_px, "largest window side, pixels (the camera is scaled to fit)")
      ->capture_default_str();
  cmd->add_option("--frames", a->frames, "stop after N frames (scripted use; 0 = until closed)")->capture_default_str();
  cmd->add_option("--screenshot", a->screenshot, "write the last frame drawn here (PNG, tone mapped)");
  cmd->add_option("--screenshot-dir", a->screenshot_dir, "where the S key saves vdrig_view_NNN.png")
      ->capture_default_str();
  cmd->add_flag("--hidden", a->hidden, "invisible window (scripted renders)");
  cmd->callback([a] { finish(run_view(*a)); });
});

}  // namespace
}  // namespace vdrig::app

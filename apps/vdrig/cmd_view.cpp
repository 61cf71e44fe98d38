// `vdrig view a.exr [b.exr ...] [--session S] [--constrained] [--gamma G] [--frames N --screenshot out.png]`: the
// interactive viewer (viewer/interactive.hpp, docs/viewer.md). Several maps of one session can be loaded (M cycles
// them). With a session, the camera is the session's (from its calibration, calib/), its captured views can be
// stepped through, shown as photographs or differences (D), and clicked texels inspected with their observations;
// without, a 1024x768 pinhole 2500 mm above the surface.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "session_data.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/viewer/interactive.hpp"

namespace vdrig::app {
namespace {

struct ViewArgs {
  std::vector<std::string> maps;
  std::string session, screenshot, screenshot_dir = ".", display = "render", inspect;
  bool constrained = false, hidden = false, no_hud = false;
  int view = 0, frames = 0, samples = 2, max_window_px = 1280, model = 0;
  double gamma = 1.0, distance_mm = 2500.0;
};

Status run_view(const ViewArgs& a) {
  std::vector<fitting::ParameterMap> maps;
  for (const auto& path : a.maps) {
    auto map = fitting::ParameterMap::read(path);
    if (!map) return make_error(map.error().code, path + ": " + map.error().message);
    maps.push_back(std::move(map.value()));
  }
  VDRIG_TRY(viewer::check_maps_compatible(maps, a.maps));
  if (a.model < 0 || a.model >= static_cast<int>(maps.size()))
    return make_error(ErrorCode::kInvalidArgument,
                      "--model must index the maps given (0.." + std::to_string(maps.size() - 1) + ")");
  viewer::ViewerOptions o;
  std::shared_ptr<SessionData> data;
  if (!a.session.empty()) {
    auto opened = open_session_data(a.session);
    if (!opened) return opened.error();
    data = std::make_shared<SessionData>(std::move(opened.value()));
    // A map fitted from another session would be compared with the wrong photographs: say so (the paths may
    // legitimately differ when a session was moved, so it is a warning).
    std::error_code ec;
    const auto session_path = std::filesystem::weakly_canonical(a.session, ec);
    for (size_t i = 0; i < maps.size(); ++i) {
      const auto& attributes = maps[i].image().string_attributes;
      const auto it = attributes.find("vdrig.source_session");
      if (it != attributes.end() && std::filesystem::weakly_canonical(it->second, ec) != session_path)
        log::get("app")->warn("{} was fitted from {}, not from --session {}", a.maps[i], it->second, a.session);
    }
    o.camera = data->geometry.camera;
    o.captured_views = data->geometry.poses;
    o.photo = [data](int view) { return data->photo(view); };
    const fitting::ParameterMap* first = &maps[0];  // all maps have its size (check_maps_compatible)
    o.observations = [data, first](int s, int t) { return data->observations(*first, s, t); };
  } else if (a.constrained) {
    return make_error(ErrorCode::kInvalidArgument, "--constrained needs --session (the captured views)");
  }
  if (a.display != "render" && !a.constrained)
    return make_error(ErrorCode::kInvalidArgument, "--display " + a.display + " needs --constrained (a captured view)");
  if (!a.inspect.empty()) {
    auto texel = parse_texel(a.inspect);
    if (!texel) return texel.error();
    if (texel->first >= maps[0].texels_s() || texel->second >= maps[0].texels_t())
      return make_error(ErrorCode::kInvalidArgument, "--inspect " + a.inspect + " is outside the map");
    o.inspect_texel = texel.value();
  }
  o.constrained = a.constrained;
  o.initial_view = a.view;
  o.initial_model = a.model;
  o.initial_display = a.display == "photo"        ? viewer::ViewerDisplay::kPhotograph
                      : a.display == "difference" ? viewer::ViewerDisplay::kDifference
                                                  : viewer::ViewerDisplay::kRender;
  o.gamma = a.gamma;
  o.distance_mm = a.distance_mm;
  o.render.samples_per_axis = a.samples;
  o.max_window_px = a.max_window_px;
  o.max_frames = a.frames;
  o.visible = !a.hidden;
  o.hud = !a.no_hud;
  o.last_frame_png = a.screenshot;
  o.screenshot_dir = a.screenshot_dir;
  auto result = viewer::run_viewer(maps, o);
  if (!result) return result.error();
  if (!a.screenshot.empty())
    std::printf("%d frames; last frame (%s, %s, %s, gamma %.3g) -> %s\n", result->frames,
                maps[result->model].model().name().c_str(),
                result->mode == viewer::ViewCamera::Mode::kConstrained
                    ? ("captured view " + std::to_string(result->view)).c_str()
                    : "free camera",
                viewer::display_name(result->display), result->gamma, a.screenshot.c_str());
  for (const auto& s : result->screenshots) std::printf("screenshot %s\n", s.c_str());
  return Status::ok();
}

const CommandRegistrar registrar([](CLI::App& root) {
  auto a = std::make_shared<ViewArgs>();
  auto* cmd = root.add_subcommand(
      "view",
      "interactive viewer of parameter maps (docs/viewer.md). Mouse: drag orbits (or steps between captured views), "
      "right drag pans, wheel zooms, ctrl+click (or middle click) inspects a texel. Keys: C free/constrained, "
      "N/P next/previous view, M next map, D render/photo/difference, I hide inspector, H heads-up line, +/- gamma, "
      "S screenshot, R reset, Esc/Q quit");
  cmd->add_option("maps", a->maps, "parameter maps (OpenEXR, from vdrig fit) of one session and size")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--session", a->session, "session folder: its camera, captured view poses and photographs");
  cmd->add_flag("--constrained", a->constrained, "start at a captured view (needs --session)");
  cmd->add_option("--view", a->view, "captured view to start at (with --constrained)")->capture_default_str();
  cmd->add_option("--map", a->model, "map to show first: its index among the maps given, from 0")
      ->capture_default_str();
  // Deprecated: --model names a model (fit, eval); here it was the map index.
  cmd->add_option("--model", a->model, "deprecated: --map")->group("")->each([](const std::string&) {
    log::get("app")->warn("view --model is deprecated: write --map (--model names a model in vdrig fit)");
  });
  cmd->add_option("--display", a->display,
                  "start showing: render | photo | difference (photo/difference need "
                  "--constrained)")
      ->capture_default_str()
      ->check(CLI::IsMember({"render", "photo", "difference"}));
  cmd->add_option("--inspect", a->inspect, "open the texel inspector on texel S,T");
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
  cmd->add_flag("--no-hud", a->no_hud, "start without the heads-up line (H toggles it)");
  cmd->callback([a] { finish(run_view(*a)); });
});

}  // namespace
}  // namespace vdrig::app

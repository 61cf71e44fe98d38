// ViewerController: what the interactive viewer does with each input (camera moves, model and display switches,
// gamma, screenshots, texel picks), without a window; and the checks of ViewerOptions. run_viewer (interactive.cpp)
// feeds it the window's events; tests feed it scripted ones.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "vdrig/core/log.hpp"
#include "vdrig/viewer/interactive.hpp"

namespace vdrig::viewer {

bool ViewerOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  std::string cam_why;
  if (camera && !camera->is_valid(&cam_why)) return fail("camera: " + cam_why);
  if (max_window_px < 16) return fail("max_window_px must be at least 16");
  if (constrained && captured_views.empty()) return fail("constrained mode needs the captured views (a session)");
  if (!captured_views.empty() && (initial_view < 0 || initial_view >= static_cast<int>(captured_views.size())))
    return fail("initial view " + std::to_string(initial_view) + " is not one of the " +
                std::to_string(captured_views.size()) + " captured views");
  if (!(gamma > 0) || !std::isfinite(gamma)) return fail("gamma must be positive");
  if (!(gamma_step > 1)) return fail("gamma_step must be > 1");
  if (!(distance_mm >= camera_settings.min_distance_mm && distance_mm <= camera_settings.max_distance_mm))
    return fail("distance must be within the orbit's distance range");
  if (render.samples_per_axis < 1 || render.samples_per_axis > 8) return fail("samples_per_axis must be in [1, 8]");
  if (max_frames < 0) return fail("max_frames must be >= 0");
  if (!(difference_gain > 0) || !std::isfinite(difference_gain)) return fail("difference_gain must be positive");
  if (initial_model < 0) return fail("initial_model must be >= 0");
  for (const auto& s : script)
    if (s.frame < 0) return fail("scripted events need frame >= 0");
  return true;
}

const char* display_name(ViewerDisplay d) {
  switch (d) {
    case ViewerDisplay::kRender:
      return "render";
    case ViewerDisplay::kPhotograph:
      return "photograph";
    case ViewerDisplay::kDifference:
      return "difference";
  }
  return "?";
}

ViewerController::ViewerController(const ViewerOptions& options, double focal_px, std::vector<std::string> model_names)
    : camera_(options.distance_mm, options.camera_settings),
      gamma_(options.gamma),
      gamma_step_(options.gamma_step),
      focal_px_(focal_px),
      model_names_(std::move(model_names)),
      has_photos_(static_cast<bool>(options.photo)),
      display_(options.initial_display),
      hud_(options.hud),
      inspected_(options.inspect_texel) {
  VDRIG_CHECK(!model_names_.empty(), "ViewerController needs at least one map");
  model_ = std::clamp(options.initial_model, 0, model_count() - 1);
  camera_.set_captured_views(options.captured_views);
  if (options.constrained) camera_.select_view(options.initial_view);
}

void ViewerController::handle(const InputEvent& e) {
  switch (e.type) {
    case InputEvent::Type::kDrag:
      camera_.drag(e.dx, e.dy);
      return;
    case InputEvent::Type::kDragEnd:
      camera_.end_drag();
      return;
    case InputEvent::Type::kPan:
      if (camera_.mode() == ViewCamera::Mode::kFree)
        camera_.pan_by(Vec2d(e.dx, e.dy) * (camera_.distance_mm() / focal_px_));
      return;
    case InputEvent::Type::kScroll:
      camera_.scroll(e.dy);
      return;
    case InputEvent::Type::kPick:
      pick_ = Vec2d(e.dx, e.dy);
      return;
    case InputEvent::Type::kKey:
      break;
  }
  switch (e.key) {
    case ViewerKey::kToggleMode:
      if (!camera_.toggle_mode()) log::get("viewer")->warn("no captured views (open with --session): free mode only");
      break;
    case ViewerKey::kNext:
      camera_.step(+1);
      break;
    case ViewerKey::kPrevious:
      camera_.step(-1);
      break;
    case ViewerKey::kGammaUp:
      gamma_ = std::min(gamma_ * gamma_step_, 1e6);
      break;
    case ViewerKey::kGammaDown:
      gamma_ = std::max(gamma_ / gamma_step_, 1e-6);
      break;
    case ViewerKey::kScreenshot:
      ++screenshot_requests_;
      break;
    case ViewerKey::kReset:
      camera_.reset();
      break;
    case ViewerKey::kQuit:
      quit_ = true;
      break;
    case ViewerKey::kNextModel:
      model_ = (model_ + 1) % model_count();
      break;
    case ViewerKey::kCycleDisplay:
      if (!at_captured_view()) {
        log::get("viewer")->warn(has_photos_ ? "photograph and difference exist at a captured view only (C, N or P)"
                                             : "no photographs (open with --session)");
        display_ = ViewerDisplay::kRender;
        break;
      }
      // From what is shown (the render, if the chosen display was suspended in free mode).
      display_ = display() == ViewerDisplay::kRender       ? ViewerDisplay::kPhotograph
                 : display() == ViewerDisplay::kPhotograph ? ViewerDisplay::kDifference
                                                           : ViewerDisplay::kRender;
      break;
    case ViewerKey::kHideInspector:
      inspected_.reset();
      break;
    case ViewerKey::kToggleHud:
      hud_ = !hud_;
      break;
  }
}

ViewerDisplay ViewerController::display() const { return at_captured_view() ? display_ : ViewerDisplay::kRender; }

bool ViewerController::take_screenshot_request() {
  if (screenshot_requests_ == 0) return false;
  --screenshot_requests_;
  return true;
}

std::optional<Vec2d> ViewerController::take_pick_request() {
  auto p = pick_;
  pick_.reset();
  return p;
}

std::string ViewerController::title() const {
  char buf[300];
  // Numbers from 0, as the console and the command line count views and maps (docs/conventions.md): "map 1 of
  // 0..2" is the map `--map 1` shows, "captured view 47 of 0..187" the view `--view 47` and `vdrig compare` name.
  const std::string model = model_count() > 1 ? model_names_[model_] + " (map " + std::to_string(model_) + " of 0.." +
                                                    std::to_string(model_count() - 1) + ")"
                                              : model_names_[model_];
  if (camera_.mode() == ViewCamera::Mode::kConstrained)
    std::snprintf(buf, sizeof buf, "vdrig view - %s - captured view %d of 0..%d - gamma %.3g", model.c_str(),
                  camera_.current_view(), camera_.captured_count() - 1, gamma_);
  else
    std::snprintf(buf, sizeof buf, "vdrig view - %s - free (azimuth %.0f, zenith %.0f deg, %.0f mm) - gamma %.3g",
                  model.c_str(), rad_to_deg(camera_.azimuth_rad()), rad_to_deg(camera_.zenith_rad()),
                  camera_.distance_mm(), gamma_);
  return buf;
}

std::string ViewerController::hud_line(double frame_ms) const {
  char buf[80];
  std::snprintf(buf, sizeof buf, " - %s - %.1f ms", display_name(display()), frame_ms);
  return title().substr(std::string("vdrig view - ").size()) + buf;
}

}  // namespace vdrig::viewer

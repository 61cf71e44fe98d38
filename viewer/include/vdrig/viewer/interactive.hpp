// The interactive viewer (`vdrig view`, docs/viewer.md): a GLFW window showing a ParameterMap through
// SurfaceRenderer::draw_tone_mapped, with the camera driven by a ViewCamera (view_camera.hpp).
//
// Controls: left drag orbits (free) or moves to the neighbouring captured view (constrained); right drag (or
// shift + left drag) pans the orbit target (free); scroll changes the distance (free); C toggles free/constrained;
// N / P next / previous captured view; + / - exposure gamma (tone mapping y = 1 - exp(-gamma x)); S saves a
// screenshot PNG; R resets; Esc / Q quits. The title shows the mode, the view index and the gamma.
//
// Testable without a mouse: GLFW callbacks only translate device input into InputEvents, and a script of
// InputEvents can be fed in at given frames; ViewerController (no OpenGL) applies every event, from either source,
// to the camera and the display state. With max_frames the loop stops by itself and can save its last frame.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/viewer/surface_renderer.hpp"
#include "vdrig/viewer/view_camera.hpp"

namespace vdrig::viewer {

enum class ViewerKey { kToggleMode, kNext, kPrevious, kGammaUp, kGammaDown, kScreenshot, kReset, kQuit };

/// One input, device independent. Drag/pan deltas are window pixels (x right, y down); scroll is in steps
/// (positive = wheel away from the user = closer).
struct InputEvent {
  enum class Type { kKey, kDrag, kDragEnd, kPan, kScroll };
  Type type = Type::kKey;
  ViewerKey key = ViewerKey::kQuit;
  double dx = 0, dy = 0;

  static InputEvent press(ViewerKey k) { return {Type::kKey, k, 0, 0}; }
  static InputEvent drag(double dx_px, double dy_px) { return {Type::kDrag, ViewerKey::kQuit, dx_px, dy_px}; }
  static InputEvent drag_end() { return {Type::kDragEnd, ViewerKey::kQuit, 0, 0}; }
  static InputEvent pan(double dx_px, double dy_px) { return {Type::kPan, ViewerKey::kQuit, dx_px, dy_px}; }
  static InputEvent scroll(double steps) { return {Type::kScroll, ViewerKey::kQuit, 0, steps}; }
};

/// An input applied just before frame `frame` (0-based) is drawn.
struct ScriptedEvent {
  int frame = 0;
  InputEvent event;
};

struct ViewerOptions {
  /// Camera intrinsics; unset: default_pinhole() of the map. A camera larger than max_window_px is shown scaled
  /// down (same field of view), and a resized window is letterboxed (fit_camera).
  std::optional<CameraModel> camera;
  int max_window_px = 1280;
  /// The session's captured view poses (constrained mode, N / P, drag to neighbour); may be empty.
  std::vector<ViewPose> captured_views;
  bool constrained = false;  // start in constrained mode at initial_view (needs captured views)
  int initial_view = 0;
  double distance_mm = 2500.0;  // free orbit distance at start and on reset
  double gamma = 1.0;           // tone mapping y = 1 - exp(-gamma x)
  double gamma_step = 1.25;     // factor per + / - press
  ViewCameraSettings camera_settings;
  RenderSettings render;
  bool visible = true;

  // Scripted use (tests, `vdrig view --frames N --screenshot out.png`).
  int max_frames = 0;                    // > 0: stop after this many frames; 0: run until the window is closed / Q
  std::vector<ScriptedEvent> script;     // applied in order at their frames
  std::filesystem::path last_frame_png;  // when set: the last frame drawn is written here (tone mapped, 8-bit)
  std::filesystem::path screenshot_dir = ".";  // S key: vdrig_view_NNN.png here (first unused NNN)

  bool is_valid(std::string* why) const;
};

/// Applies input to the camera and display state; no OpenGL, so its rules are unit-testable.
class ViewerController {
 public:
  /// `focal_px` converts pan drags to millimetres at the target (mm per pixel = distance / focal_px).
  ViewerController(const ViewerOptions& options, double focal_px);

  void handle(const InputEvent& event);

  const ViewCamera& camera() const { return camera_; }
  ViewCamera& camera() { return camera_; }
  double gamma() const { return gamma_; }
  bool quit_requested() const { return quit_; }
  /// True once per S press.
  bool take_screenshot_request();
  /// Window title: mode, view index (1-based, of the count) or orbit, gamma.
  std::string title() const;

 private:
  ViewCamera camera_;
  double gamma_, gamma_step_, focal_px_;
  bool quit_ = false;
  int screenshot_requests_ = 0;
};

/// A distortion-free camera of width x height pixels whose view, from distance_mm straight above the surface
/// centre, shows the whole width_mm x height_mm surface with a 10% margin.
CameraModel default_pinhole(double width_mm, double height_mm, int width = 1024, int height = 768,
                            double distance_mm = 2500.0);

/// `camera` uniformly scaled to a width x height framebuffer (same field of view, centred, letterboxed when the
/// aspect differs); the identity when the size already matches. Distortion coefficients are unchanged (they act
/// on normalised coordinates).
CameraModel fit_camera(const CameraModel& camera, int width, int height);

struct ViewerResult {
  int frames = 0;      // frames drawn
  cv::Mat last_frame;  // CV_8UC3 BGR, tone mapped; filled when last_frame_png is set or max_frames > 0
  ViewCamera::Mode mode = ViewCamera::Mode::kFree;
  int view = -1;  // current captured view at exit
  double gamma = 1.0;
  ViewPose pose;             // camera pose of the last frame
  CameraModel frame_camera;  // intrinsics of the last frame (the camera fitted to the framebuffer)
  std::vector<std::filesystem::path> screenshots;
};

/// Opens a window (GlContext: kUnsupported without a display) and runs the viewer until it is closed, Q / Esc, or
/// max_frames. Errors: invalid options (kInvalidArgument), a map the renderer cannot shade, OpenGL or PNG failures.
Result<ViewerResult> run_viewer(const fitting::ParameterMap& map, const ViewerOptions& options);

}  // namespace vdrig::viewer

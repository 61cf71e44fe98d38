// The interactive viewer (`vdrig view`, docs/viewer.md): a GLFW window showing a ParameterMap through
// SurfaceRenderer::draw_tone_mapped, with the camera driven by a ViewCamera (view_camera.hpp).
//
// Controls: left drag orbits (free) or moves to the neighbouring captured view (constrained); right drag (or
// shift + left drag) pans the orbit target (free); scroll changes the distance (free); C toggles free/constrained;
// N / P next / previous captured view; M cycles the maps (models) loaded; D cycles render / photograph / difference
// at a captured view; ctrl + left click (or middle click) inspects a texel (texel_inspector.hpp), I hides the
// inspector; H toggles the heads-up line; + / - exposure gamma (tone mapping y = 1 - exp(-gamma x)); S saves a
// screenshot PNG; R resets; Esc / Q quits. The title and the heads-up line show the model, the mode, the view index
// or orbit angles, the gamma and the frame time.
//
// Testable without a mouse: GLFW callbacks only translate device input into InputEvents, and a script of
// InputEvents can be fed in at given frames; ViewerController (no OpenGL) applies every event, from either source,
// to the camera and the display state. With max_frames the loop stops by itself and can save its last frame.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/viewer/surface_renderer.hpp"
#include "vdrig/viewer/view_camera.hpp"

namespace vdrig::viewer {

enum class ViewerKey {
  kToggleMode,
  kNext,
  kPrevious,
  kGammaUp,
  kGammaDown,
  kScreenshot,
  kReset,
  kQuit,
  kNextModel,      // M: the next map loaded (wrapping)
  kCycleDisplay,   // D: render -> photograph -> difference -> render (at a captured view with photographs)
  kHideInspector,  // I
  kToggleHud,      // H
};

/// What the window shows. Photograph and difference exist only at a captured view (constrained mode) of a session
/// whose photographs are available (ViewerOptions::photo); elsewhere the render is shown.
///  - kPhotograph: the view's HDR image, tone mapped as the render;
///  - kDifference: |tone_map(render) - tone_map(photo)| x difference_gain, in 8-bit codes per channel.
enum class ViewerDisplay { kRender, kPhotograph, kDifference };
const char* display_name(ViewerDisplay d);

/// One input, device independent. Drag/pan deltas are window pixels (x right, y down); scroll is in steps
/// (positive = wheel away from the user = closer); a pick is the framebuffer pixel (x right, y down) clicked to
/// inspect the texel there.
struct InputEvent {
  enum class Type { kKey, kDrag, kDragEnd, kPan, kScroll, kPick };
  Type type = Type::kKey;
  ViewerKey key = ViewerKey::kQuit;
  double dx = 0, dy = 0;

  static InputEvent press(ViewerKey k) { return {Type::kKey, k, 0, 0}; }
  static InputEvent drag(double dx_px, double dy_px) { return {Type::kDrag, ViewerKey::kQuit, dx_px, dy_px}; }
  static InputEvent drag_end() { return {Type::kDragEnd, ViewerKey::kQuit, 0, 0}; }
  static InputEvent pan(double dx_px, double dy_px) { return {Type::kPan, ViewerKey::kQuit, dx_px, dy_px}; }
  static InputEvent scroll(double steps) { return {Type::kScroll, ViewerKey::kQuit, 0, steps}; }
  static InputEvent pick(double x_px, double y_px) { return {Type::kPick, ViewerKey::kQuit, x_px, y_px}; }
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
  bool hud = true;  // the heads-up line over the top of the frame (H toggles it)

  // Session data (optional; the viewer library does not read sessions itself, the caller supplies loaders).
  /// Captured view k's photograph: linear radiance, CV_32FC3 BGR, camera-sized (the session's HDR image). Unset:
  /// no photograph or difference display.
  std::function<Result<cv::Mat>(int view)> photo;
  /// The observations of texel (s, t), every view (held-out ones included), for the inspector. Unset: clicking a
  /// texel shows its parameters and the model's curve without observations.
  std::function<Result<fitting::TexelObservations>(int s, int t)> observations;
  ViewerDisplay initial_display = ViewerDisplay::kRender;
  int initial_model = 0;                             // index into the maps
  std::optional<std::pair<int, int>> inspect_texel;  // open the inspector on this texel at start
  double difference_gain = 4.0;                      // kDifference amplification of the code difference

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
  /// `focal_px` converts pan drags to millimetres at the target (mm per pixel = distance / focal_px); `model_names`
  /// are the maps loaded (at least one), in the order M cycles through them.
  ViewerController(const ViewerOptions& options, double focal_px, std::vector<std::string> model_names = {"map"});

  void handle(const InputEvent& event);

  const ViewCamera& camera() const { return camera_; }
  ViewCamera& camera() { return camera_; }
  double gamma() const { return gamma_; }
  bool quit_requested() const { return quit_; }
  /// True once per S press.
  bool take_screenshot_request();
  /// Window title: model, mode, view index (1-based, of the count) or orbit, gamma.
  std::string title() const;
  /// The heads-up line: the title's fields, the display and the frame time.
  std::string hud_line(double frame_ms) const;

  int model() const { return model_; }
  int model_count() const { return static_cast<int>(model_names_.size()); }
  /// What is shown now: the display chosen with D, or the render where that display does not exist (free mode, no
  /// photographs).
  ViewerDisplay display() const;
  bool hud() const { return hud_; }
  /// The texel the inspector shows, if open.
  const std::optional<std::pair<int, int>>& inspected() const { return inspected_; }
  void inspect(std::optional<std::pair<int, int>> texel) { inspected_ = texel; }
  /// The pixel of the last pick not yet resolved into a texel (the window loop does that: it knows the camera).
  std::optional<Vec2d> take_pick_request();

 private:
  bool at_captured_view() const { return camera_.mode() == ViewCamera::Mode::kConstrained && has_photos_; }

  ViewCamera camera_;
  double gamma_, gamma_step_, focal_px_;
  std::vector<std::string> model_names_;
  int model_ = 0;
  bool has_photos_ = false;
  ViewerDisplay display_ = ViewerDisplay::kRender;
  bool hud_ = true;
  std::optional<std::pair<int, int>> inspected_;
  std::optional<Vec2d> pick_;
  bool quit_ = false;
  int screenshot_requests_ = 0;
};

/// Maps can be shown together when they cover the same surface with the same texels and come from the same session
/// (vdrig.source_session, when both record one); kInvalidArgument naming the first map that differs and how.
/// `names` label the maps in the message (file names), parallel to `maps`.
Status check_maps_compatible(std::span<const fitting::ParameterMap> maps, std::span<const std::string> names);

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
  int model = 0;             // map shown at exit
  ViewerDisplay display = ViewerDisplay::kRender;
  std::optional<std::pair<int, int>> inspected;
  std::vector<std::filesystem::path> screenshots;
};

/// Opens a window (GlContext: kUnsupported without a display) and runs the viewer until it is closed, Q / Esc, or
/// max_frames. Errors: invalid options (kInvalidArgument), maps that cannot be shown together
/// (check_maps_compatible), a map the renderer cannot shade, OpenGL or PNG failures, a photograph that cannot be
/// loaded or has another size than the camera.
Result<ViewerResult> run_viewer(std::span<const fitting::ParameterMap> maps, const ViewerOptions& options);
/// One map.
Result<ViewerResult> run_viewer(const fitting::ParameterMap& map, const ViewerOptions& options);

}  // namespace vdrig::viewer

#include "vdrig/viewer/interactive.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::viewer {
namespace {

/// What the GLFW callbacks share with the loop: device input becomes InputEvents in `queue`.
struct WindowInput {
  std::deque<InputEvent> queue;
  bool orbiting = false, panning = false;
  bool refresh = true;  // the window needs redrawing (exposed, resized); input also triggers a redraw
  double last_x = 0, last_y = 0;
};

WindowInput* input_of(GLFWwindow* w) { return static_cast<WindowInput*>(glfwGetWindowUserPointer(w)); }

void on_key(GLFWwindow* w, int key, int /*scancode*/, int action, int /*mods*/) {
  if (action == GLFW_RELEASE) return;
  const bool repeat = action == GLFW_REPEAT;
  std::optional<ViewerKey> k;
  switch (key) {
    case GLFW_KEY_C:
      k = ViewerKey::kToggleMode;
      break;
    case GLFW_KEY_N:
      k = ViewerKey::kNext;
      break;
    case GLFW_KEY_P:
      k = ViewerKey::kPrevious;
      break;
    case GLFW_KEY_EQUAL:  // '+' is shift + '=' on most layouts
    case GLFW_KEY_KP_ADD:
      k = ViewerKey::kGammaUp;
      break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT:
      k = ViewerKey::kGammaDown;
      break;
    case GLFW_KEY_S:
      k = ViewerKey::kScreenshot;
      break;
    case GLFW_KEY_R:
      k = ViewerKey::kReset;
      break;
    case GLFW_KEY_Q:
    case GLFW_KEY_ESCAPE:
      k = ViewerKey::kQuit;
      break;
    default:
      return;
  }
  // Auto-repeat only for the keys where holding makes sense.
  if (repeat && *k != ViewerKey::kNext && *k != ViewerKey::kPrevious && *k != ViewerKey::kGammaUp &&
      *k != ViewerKey::kGammaDown)
    return;
  input_of(w)->queue.push_back(InputEvent::press(*k));
}

void on_mouse_button(GLFWwindow* w, int button, int action, int mods) {
  WindowInput* in = input_of(w);
  glfwGetCursorPos(w, &in->last_x, &in->last_y);
  const bool press = action == GLFW_PRESS;
  if (button == GLFW_MOUSE_BUTTON_LEFT && !(mods & GLFW_MOD_SHIFT)) {
    in->orbiting = press;
    if (!press) in->queue.push_back(InputEvent::drag_end());
  } else if (button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_LEFT) {
    in->panning = press;
  }
}

void on_cursor(GLFWwindow* w, double x, double y) {
  WindowInput* in = input_of(w);
  const double dx = x - in->last_x, dy = y - in->last_y;
  in->last_x = x;
  in->last_y = y;
  if (in->orbiting)
    in->queue.push_back(InputEvent::drag(dx, dy));
  else if (in->panning)
    in->queue.push_back(InputEvent::pan(dx, dy));
}

void on_scroll(GLFWwindow* w, double /*x*/, double y) { input_of(w)->queue.push_back(InputEvent::scroll(y)); }

void on_refresh(GLFWwindow* w) { input_of(w)->refresh = true; }

/// The back buffer as CV_8UC3 BGR, OpenCV row order (row 0 at the top).
Result<cv::Mat> read_back_buffer(int width, int height) {
  cv::Mat rgba(height, width, CV_8UC4);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data);
  if (const GLenum e = glGetError(); e != GL_NO_ERROR)
    return make_error(ErrorCode::kInternal, "OpenGL error " + std::to_string(e) + " reading the window back");
  cv::Mat bgr;
  cv::cvtColor(rgba, bgr, cv::COLOR_RGBA2BGR);
  cv::flip(bgr, bgr, 0);  // GL row 0 is the bottom of the window
  return bgr;
}

std::filesystem::path next_screenshot_path(const std::filesystem::path& dir) {
  for (int i = 1;; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "vdrig_view_%03d.png", i);
    const auto p = dir / name;
    if (!std::filesystem::exists(p)) return p;
  }
}

}  // namespace

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
  for (const auto& s : script)
    if (s.frame < 0) return fail("scripted events need frame >= 0");
  return true;
}

ViewerController::ViewerController(const ViewerOptions& options, double focal_px)
    : camera_(options.distance_mm, options.camera_settings),
      gamma_(options.gamma),
      gamma_step_(options.gamma_step),
      focal_px_(focal_px) {
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
  }
}

bool ViewerController::take_screenshot_request() {
  if (screenshot_requests_ == 0) return false;
  --screenshot_requests_;
  return true;
}

std::string ViewerController::title() const {
  char buf[200];
  if (camera_.mode() == ViewCamera::Mode::kConstrained)
    std::snprintf(buf, sizeof buf, "vdrig view - captured view %d/%d - gamma %.3g", camera_.current_view() + 1,
                  camera_.captured_count(), gamma_);
  else
    std::snprintf(buf, sizeof buf, "vdrig view - free (azimuth %.0f, zenith %.0f deg, %.0f mm) - gamma %.3g",
                  rad_to_deg(camera_.azimuth_rad()), rad_to_deg(camera_.zenith_rad()), camera_.distance_mm(), gamma_);
  return buf;
}

CameraModel default_pinhole(double width_mm, double height_mm, int width, int height, double distance_mm) {
  VDRIG_CHECK(width_mm > 0 && height_mm > 0 && width > 0 && height > 0 && distance_mm > 0,
              "default_pinhole needs positive sizes");
  CameraModel c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = distance_mm * std::min(width / (1.1 * width_mm), height / (1.1 * height_mm));
  c.cx = (width - 1) / 2.0;
  c.cy = (height - 1) / 2.0;
  return c;
}

CameraModel fit_camera(const CameraModel& cam, int width, int height) {
  if (cam.width == width && cam.height == height) return cam;
  const double s = std::min(static_cast<double>(width) / cam.width, static_cast<double>(height) / cam.height);
  CameraModel c = cam;
  c.width = width;
  c.height = height;
  c.fx = cam.fx * s;
  c.fy = cam.fy * s;
  // Pixel centres: continuous coordinate x + 0.5 scales by s; the letterbox offset centres the scaled image.
  c.cx = (cam.cx + 0.5) * s - 0.5 + 0.5 * (width - cam.width * s);
  c.cy = (cam.cy + 0.5) * s - 0.5 + 0.5 * (height - cam.height * s);
  return c;
}

Result<ViewerResult> run_viewer(const fitting::ParameterMap& map, const ViewerOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "viewer options: " + why);
  auto logger = log::get("viewer");
  const CameraModel base =
      options.camera ? *options.camera : default_pinhole(map.width_mm(), map.height_mm(), 1024, 768);
  // Window: the camera's image, scaled down to fit max_window_px.
  const double shrink = std::min(1.0, static_cast<double>(options.max_window_px) / std::max(base.width, base.height));
  const int win_w = std::max(1, static_cast<int>(std::lround(base.width * shrink)));
  const int win_h = std::max(1, static_cast<int>(std::lround(base.height * shrink)));

  ViewerController controller(options, base.fx * shrink);
  auto ctx = GlContext::create(win_w, win_h, options.visible, controller.title());
  if (!ctx) return ctx.error();
  auto renderer = SurfaceRenderer::create(map);
  if (!renderer) return renderer.error();
  GLFWwindow* window = (*ctx)->window();
  logger->info("viewer: {}x{} window, OpenGL renderer {}", win_w, win_h, (*ctx)->renderer());

  WindowInput input;
  glfwSetWindowUserPointer(window, &input);
  glfwSetKeyCallback(window, on_key);
  glfwSetMouseButtonCallback(window, on_mouse_button);
  glfwSetCursorPosCallback(window, on_cursor);
  glfwSetScrollCallback(window, on_scroll);
  glfwSetWindowRefreshCallback(window, on_refresh);
  const bool scripted = options.max_frames > 0;
  glfwSwapInterval(scripted ? 0 : 1);  // scripted runs go as fast as they can
  const bool keep_frames = scripted || !options.last_frame_png.empty();

  ViewerResult result;
  std::string title = controller.title();
  size_t next_scripted = 0;
  // Scripted events in frame order (stable: events of one frame keep their order).
  std::vector<ScriptedEvent> script = options.script;
  std::stable_sort(script.begin(), script.end(),
                   [](const ScriptedEvent& a, const ScriptedEvent& b) { return a.frame < b.frame; });

  Status status = Status::ok();
  for (int frame = 0; !scripted || frame < options.max_frames; ++frame) {
    if (scripted)
      glfwPollEvents();
    else
      glfwWaitEventsTimeout(0.5);  // sleeps until input: redraws on input, exposure or resize only
    while (next_scripted < script.size() && script[next_scripted].frame <= frame)
      input.queue.push_back(script[next_scripted++].event);
    bool redraw = scripted || input.refresh || !input.queue.empty();
    input.refresh = false;
    while (!input.queue.empty()) {
      controller.handle(input.queue.front());
      input.queue.pop_front();
    }
    if (controller.quit_requested() || glfwWindowShouldClose(window)) break;
    if (const std::string t = controller.title(); t != title) {
      title = t;
      glfwSetWindowTitle(window, title.c_str());
    }

    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(window, &fb_w, &fb_h);
    if (fb_w <= 0 || fb_h <= 0) continue;  // minimised
    redraw = redraw || fb_w != result.frame_camera.width || fb_h != result.frame_camera.height;
    if (!redraw) continue;  // interactive and idle: nothing changed since the last frame
    const CameraModel cam = fit_camera(base, fb_w, fb_h);
    const ViewPose pose = controller.camera().pose();
    glViewport(0, 0, fb_w, fb_h);
    (*renderer)->draw_tone_mapped(cam, pose, options.render, controller.gamma());
    const bool screenshot = controller.take_screenshot_request();
    if (keep_frames || screenshot) {
      auto img = read_back_buffer(fb_w, fb_h);
      if (!img) {
        status = img.error();
        break;
      }
      if (screenshot) {
        const auto path = next_screenshot_path(options.screenshot_dir);
        if (Status s = write_png(path, img.value()); !s) {
          status = s;
          break;
        }
        logger->info("screenshot {}", path.string());
        result.screenshots.push_back(path);
      }
      if (keep_frames) result.last_frame = std::move(img.value());
    }
    glfwSwapBuffers(window);
    ++result.frames;
    result.pose = pose;
    result.frame_camera = cam;
  }
  glfwSetWindowUserPointer(window, nullptr);
  if (!status) return status.error();
  result.mode = controller.camera().mode();
  result.view = controller.camera().current_view();
  result.gamma = controller.gamma();
  if (!options.last_frame_png.empty()) {
    if (result.last_frame.empty()) return make_error(ErrorCode::kInternal, "no frame was drawn");
    VDRIG_TRY(write_png(options.last_frame_png, result.last_frame));
  }
  return result;
}

}  // namespace vdrig::viewer

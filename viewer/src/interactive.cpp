#include "vdrig/viewer/interactive.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>
#include <GLFW/glfw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/gl/program.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

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
    case GLFW_KEY_M:
      k = ViewerKey::kNextModel;
      break;
    case GLFW_KEY_D:
      k = ViewerKey::kCycleDisplay;
      break;
    case GLFW_KEY_I:
      k = ViewerKey::kHideInspector;
      break;
    case GLFW_KEY_H:
      k = ViewerKey::kToggleHud;
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
  if (press &&
      (button == GLFW_MOUSE_BUTTON_MIDDLE || (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_CONTROL)))) {
    // Window coordinates to framebuffer pixels (they differ on high-DPI screens).
    int win_w = 1, win_h = 1, fb_w = 1, fb_h = 1;
    glfwGetWindowSize(w, &win_w, &win_h);
    glfwGetFramebufferSize(w, &fb_w, &fb_h);
    in->queue.push_back(
        InputEvent::pick(in->last_x * fb_w / std::max(1, win_w) - 0.5, in->last_y * fb_h / std::max(1, win_h) - 0.5));
    return;
  }
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

/// Draws an 8-bit BGR image into a rectangle of the default framebuffer: the photograph, the difference image, the
/// heads-up line and the inspector plot.
class ImageQuad {
 public:
  ImageQuad() {
    const char* vs = R"(#version 330 core
out vec2 v_uv;
void main() {
  vec2 corner = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
  v_uv = vec2(corner.x, 1.0 - corner.y);  // image row 0 at the top
  gl_Position = vec4(2.0 * corner - 1.0, 0.0, 1.0);
}
)";
    const char* fs = R"(#version 330 core
in vec2 v_uv;
out vec4 out_colour;
uniform sampler2D u_image;
void main() { out_colour = vec4(texture(u_image, v_uv).rgb, 1.0); }
)";
    auto program = gl::link_program(vs, fs, "the viewer's image shader");
    // Fixed source: a failure is a broken invariant.
    VDRIG_CHECK(program.is_ok(), program.error().describe());
    program_ = program.value();
    glGenVertexArrays(1, &vao_);
    glGenTextures(1, &texture_);
  }
  ~ImageQuad() {
    glDeleteTextures(1, &texture_);
    glDeleteVertexArrays(1, &vao_);
    glDeleteProgram(program_);
  }
  ImageQuad(const ImageQuad&) = delete;
  ImageQuad& operator=(const ImageQuad&) = delete;

  /// `rect` in framebuffer pixels, (0, 0) = top left.
  void draw(const cv::Mat& bgr, const cv::Rect& rect, int fb_height) {
    VDRIG_CHECK(bgr.type() == CV_8UC3 && bgr.isContinuous(), "ImageQuad draws continuous CV_8UC3 images");
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(rect.x, fb_height - rect.y - rect.height, rect.width, rect.height);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, bgr.cols, bgr.rows, 0, GL_BGR, GL_UNSIGNED_BYTE, bgr.data);
    const bool same_size = bgr.cols == rect.width && bgr.rows == rect.height;
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, same_size ? GL_NEAREST : GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, same_size ? GL_NEAREST : GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glUseProgram(program_);
    glUniform1i(glGetUniformLocation(program_, "u_image"), 0);
    glBindVertexArray(vao_);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  }

 private:
  GLuint program_ = 0, vao_ = 0, texture_ = 0;
};

/// The framebuffer rectangle a camera image fills when scaled to fit (fit_camera's letterbox).
cv::Rect letterbox(const CameraModel& camera, int fb_w, int fb_h) {
  const double s = std::min(static_cast<double>(fb_w) / camera.width, static_cast<double>(fb_h) / camera.height);
  const int w = std::max(1, static_cast<int>(std::lround(camera.width * s)));
  const int h = std::max(1, static_cast<int>(std::lround(camera.height * s)));
  return {(fb_w - w) / 2, (fb_h - h) / 2, w, h};
}

/// The heads-up line as an image strip `width` pixels wide.
cv::Mat hud_strip(const std::string& line, int width) {
  cv::Mat strip(22, std::max(1, width), CV_8UC3, cv::Scalar(25, 25, 25));
  cv::putText(strip, line, cv::Point(6, 16), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(235, 235, 235), 1, cv::LINE_AA);
  return strip;
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
  const std::string model = model_count() > 1 ? model_names_[model_] + " (" + std::to_string(model_ + 1) + "/" +
                                                    std::to_string(model_count()) + ")"
                                              : model_names_[model_];
  if (camera_.mode() == ViewCamera::Mode::kConstrained)
    std::snprintf(buf, sizeof buf, "vdrig view - %s - captured view %d/%d - gamma %.3g", model.c_str(),
                  camera_.current_view() + 1, camera_.captured_count(), gamma_);
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

Status check_maps_compatible(std::span<const fitting::ParameterMap> maps, std::span<const std::string> names) {
  VDRIG_CHECK(names.size() == maps.size(), "check_maps_compatible: one name per map");
  if (maps.empty()) return make_error(ErrorCode::kInvalidArgument, "no map to show");
  const auto& first = maps[0];
  auto session_of = [](const fitting::ParameterMap& m) {
    const auto it = m.image().string_attributes.find("vdrig.source_session");
    return it == m.image().string_attributes.end() ? std::string() : it->second;
  };
  for (size_t i = 1; i < maps.size(); ++i) {
    const auto& m = maps[i];
    auto refuse = [&](const std::string& how) {
      return make_error(ErrorCode::kInvalidArgument, "maps shown together must be of one session and size: " +
                                                         names[i] + " " + how + " (" + names[0] + ")");
    };
    if (m.texels_s() != first.texels_s() || m.texels_t() != first.texels_t())
      return refuse("has " + std::to_string(m.texels_s()) + "x" + std::to_string(m.texels_t()) + " texels, not " +
                    std::to_string(first.texels_s()) + "x" + std::to_string(first.texels_t()));
    if (m.width_mm() != first.width_mm() || m.height_mm() != first.height_mm())
      return refuse("covers a surface of another size");
    const std::string a = session_of(first), b = session_of(m);
    if (!a.empty() && !b.empty() && a != b) return refuse("comes from session " + b + ", not " + a);
  }
  return Status::ok();
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
  return run_viewer(std::span<const fitting::ParameterMap>(&map, 1), options);
}

Result<ViewerResult> run_viewer(std::span<const fitting::ParameterMap> maps, const ViewerOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "viewer options: " + why);
  std::vector<std::string> names;
  for (const auto& m : maps) names.push_back(m.model().name());
  VDRIG_TRY(check_maps_compatible(maps, names));
  auto logger = log::get("viewer");
  const fitting::ParameterMap& first = maps[0];
  const CameraModel base =
      options.camera ? *options.camera : default_pinhole(first.width_mm(), first.height_mm(), 1024, 768);
  // Window: the camera's image, scaled down to fit max_window_px.
  const double shrink = std::min(1.0, static_cast<double>(options.max_window_px) / std::max(base.width, base.height));
  const int win_w = std::max(1, static_cast<int>(std::lround(base.width * shrink)));
  const int win_h = std::max(1, static_cast<int>(std::lround(base.height * shrink)));

  ViewerController controller(options, base.fx * shrink, names);
  auto ctx = GlContext::create(win_w, win_h, options.visible, controller.title());
  if (!ctx) return ctx.error();
  std::vector<std::unique_ptr<SurfaceRenderer>> renderers;
  for (const auto& m : maps) {
    auto renderer = SurfaceRenderer::create(m);
    if (!renderer) return renderer.error();
    renderers.push_back(std::move(renderer.value()));
  }
  ImageQuad quad;
  GLFWwindow* window = (*ctx)->window();
  logger->info("viewer: {} map(s), {}x{} window, OpenGL renderer {}", maps.size(), win_w, win_h, (*ctx)->renderer());

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

  // Photographs (linear radiance) by view, loaded once each; tone-mapped images and the inspector plot are remade
  // only when what they depend on changes.
  std::map<int, cv::Mat> photos;
  auto photo_of = [&](int view) -> Result<cv::Mat> {
    if (auto it = photos.find(view); it != photos.end()) return it->second;
    auto photo = options.photo(view);
    if (!photo) return photo.error();
    if (photo->type() != CV_32FC3 || photo->cols != base.width || photo->rows != base.height)
      return make_error(ErrorCode::kCorrupt, "the photograph of view " + std::to_string(view) +
                                                 " is not a camera-sized radiance image (" +
                                                 std::to_string(base.width) + "x" + std::to_string(base.height) + ")");
    photos[view] = photo.value();
    return photo;
  };
  std::string shown_key;  // what `shown` holds: display, model, view, gamma
  cv::Mat shown;
  std::pair<int, int> plotted_texel{-1, -1};  // (-1, -1): no plot yet
  int plotted_model = -1;
  cv::Mat plot;

  ViewerResult result;
  std::string title = controller.title();
  size_t next_scripted = 0;
  // Scripted events in frame order (stable: events of one frame keep their order).
  std::vector<ScriptedEvent> script = options.script;
  std::stable_sort(script.begin(), script.end(),
                   [](const ScriptedEvent& a, const ScriptedEvent& b) { return a.frame < b.frame; });

  double frame_ms = 0;
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
    const CameraModel cam = fit_camera(base, fb_w, fb_h);
    const ViewPose pose = controller.camera().pose();
    if (const auto pixel = controller.take_pick_request()) {
      controller.inspect(pick_texel(cam, pose, first, pixel.value()));
      if (!controller.inspected()) logger->info("no texel under the clicked pixel");
    }
    if (!redraw) continue;  // interactive and idle: nothing changed since the last frame
    const auto start = std::chrono::steady_clock::now();
    SurfaceRenderer& renderer = *renderers[controller.model()];
    const ViewerDisplay display = controller.display();
    if (display == ViewerDisplay::kRender) {
      glViewport(0, 0, fb_w, fb_h);
      renderer.draw_tone_mapped(cam, pose, options.render, controller.gamma());
    } else {
      const int view = controller.camera().current_view();
      const std::string key = std::string(display_name(display)) + " " + std::to_string(controller.model()) + " " +
                              std::to_string(view) + " " + std::to_string(controller.gamma());
      if (key != shown_key) {
        auto photo = photo_of(view);
        if (!photo) {
          status = photo.error();
          break;
        }
        shown = tone_map(photo.value(), controller.gamma());
        if (display == ViewerDisplay::kDifference) {
          auto radiance = renderer.render_radiance(base, pose, options.render);
          if (!radiance) {
            status = radiance.error();
            break;
          }
          cv::Mat diff;
          cv::absdiff(tone_map(radiance.value(), controller.gamma()), shown, diff);
          diff.convertTo(shown, CV_8UC3, options.difference_gain);
        }
        shown_key = key;
      }
      glBindFramebuffer(GL_FRAMEBUFFER, 0);
      glViewport(0, 0, fb_w, fb_h);
      glClearColor(0.05f, 0.05f, 0.06f, 1);
      glClear(GL_COLOR_BUFFER_BIT);
      quad.draw(shown, letterbox(base, fb_w, fb_h), fb_h);
    }
    if (controller.inspected()) {
      if (*controller.inspected() != plotted_texel || controller.model() != plotted_model) {
        const auto [s, t] = controller.inspected().value();
        const fitting::ParameterMap& map = maps[controller.model()];
        fitting::TexelObservations obs;
        if (options.observations) {
          auto loaded = options.observations(s, t);
          if (loaded)
            obs = std::move(loaded.value());
          else
            logger->warn("texel {},{}: no observations ({})", s, t, loaded.error().describe());
        }
        // Drawn at the size `vdrig inspect` draws it (its layout is laid out for it), shrunk below to fit.
        plot = plot_inspection(inspect_texel(map, s, t, obs, held_out_views(map)));
        plotted_texel = *controller.inspected();
        plotted_model = controller.model();
      }
      // Lower right, at most three quarters of the window wide and tall.
      const double f =
          std::min({1.0, 0.75 * fb_w / static_cast<double>(plot.cols), 0.75 * fb_h / static_cast<double>(plot.rows)});
      const cv::Size size(std::max(1, static_cast<int>(plot.cols * f)), std::max(1, static_cast<int>(plot.rows * f)));
      cv::Mat scaled = plot;
      if (size != plot.size()) cv::resize(plot, scaled, size, 0, 0, cv::INTER_AREA);
      quad.draw(scaled, cv::Rect(fb_w - size.width, fb_h - size.height, size.width, size.height), fb_h);
    }
    if (controller.hud()) {
      const cv::Mat strip = hud_strip(controller.hud_line(frame_ms), fb_w);
      quad.draw(strip, cv::Rect(0, 0, strip.cols, std::min(strip.rows, fb_h)), fb_h);
    }
    glFinish();
    frame_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
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
  result.model = controller.model();
  result.display = controller.display();
  result.inspected = controller.inspected();
  if (!options.last_frame_png.empty()) {
    if (result.last_frame.empty()) return make_error(ErrorCode::kInternal, "no frame was drawn");
    VDRIG_TRY(write_png(options.last_frame_png, result.last_frame));
  }
  return result;
}

}  // namespace vdrig::viewer

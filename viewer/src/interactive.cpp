// run_viewer: the interactive viewer's window, its event loop and drawing (input: glfw_input.cpp; what input does:
// viewer_controller.cpp; images into and out of the window: window_images.cpp).
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

#include "glfw_input.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/gl/program.hpp"
#include "vdrig/viewer/texel_inspector.hpp"
#include "window_images.hpp"

namespace vdrig::viewer {

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
  attach_input_callbacks(window, &input);
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
  detach_input_callbacks(window);
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

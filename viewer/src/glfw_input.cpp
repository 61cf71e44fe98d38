#include "glfw_input.hpp"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <optional>

namespace vdrig::viewer {
namespace {

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

}  // namespace

void attach_input_callbacks(GLFWwindow* window, WindowInput* input) {
  glfwSetWindowUserPointer(window, input);
  glfwSetKeyCallback(window, on_key);
  glfwSetMouseButtonCallback(window, on_mouse_button);
  glfwSetCursorPosCallback(window, on_cursor);
  glfwSetScrollCallback(window, on_scroll);
  glfwSetWindowRefreshCallback(window, on_refresh);
}

void detach_input_callbacks(GLFWwindow* window) {
  glfwSetKeyCallback(window, nullptr);
  glfwSetMouseButtonCallback(window, nullptr);
  glfwSetCursorPosCallback(window, nullptr);
  glfwSetScrollCallback(window, nullptr);
  glfwSetWindowRefreshCallback(window, nullptr);
  glfwSetWindowUserPointer(window, nullptr);
}

}  // namespace vdrig::viewer

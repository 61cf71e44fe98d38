// GLFW input of the interactive viewer: the window's key, mouse, scroll and refresh callbacks turned into
// InputEvents (interactive.hpp) queued for the loop of run_viewer, which hands them to the ViewerController.
#pragma once

#include <deque>

#include "vdrig/viewer/interactive.hpp"

struct GLFWwindow;

namespace vdrig::viewer {

/// What the GLFW callbacks share with the loop: device input becomes InputEvents in `queue`.
struct WindowInput {
  std::deque<InputEvent> queue;
  bool orbiting = false, panning = false;
  bool refresh = true;  // the window needs redrawing (exposed, resized); input also triggers a redraw
  double last_x = 0, last_y = 0;
};

/// Points the window's callbacks at `input`, which must outlive them (until detach_input_callbacks).
void attach_input_callbacks(GLFWwindow* window, WindowInput* input);
/// Forgets `input` (the callbacks then find no input and GLFW is told to call none).
void detach_input_callbacks(GLFWwindow* window);

}  // namespace vdrig::viewer

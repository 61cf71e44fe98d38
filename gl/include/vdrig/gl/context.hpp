// The project's one OpenGL setup: a GLFW window holding an OpenGL 3.3 core context. The viewer renders parameter
// maps in it and probe_gl fuses probes in it; both take it from here, so neither links the other.
#pragma once

#include <memory>
#include <string>

#include "vdrig/core/result.hpp"

struct GLFWwindow;

namespace vdrig::gl {

/// An OpenGL 3.3 core context from GLFW: an invisible window for headless rendering (needs an X display: Xvfb in
/// CI), or a visible one for the interactive viewer. One per thread; current once created.
class Context {
 public:
  /// kUnsupported when GLFW cannot start (no display) or the driver has no OpenGL 3.3 core context.
  static Result<std::unique_ptr<Context>> create(int width, int height, bool visible,
                                                 const std::string& title = "vdrig");
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  GLFWwindow* window() const { return window_; }
  void make_current();
  std::string renderer() const;  // GL_RENDERER string

 private:
  Context() = default;
  GLFWwindow* window_ = nullptr;
};

}  // namespace vdrig::gl

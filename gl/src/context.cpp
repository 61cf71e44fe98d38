#include "vdrig/gl/context.hpp"

#include <GL/gl.h>
#include <GLFW/glfw3.h>

#include <algorithm>
#include <mutex>

#include "vdrig/core/log.hpp"

namespace vdrig::gl {
namespace {

std::once_flag g_glfw_once;
bool g_glfw_ok = false;

}  // namespace

Result<std::unique_ptr<Context>> Context::create(int width, int height, bool visible, const std::string& title) {
  std::call_once(g_glfw_once, [] {
    glfwSetErrorCallback([](int code, const char* msg) { log::get("gl")->warn("GLFW error {}: {}", code, msg); });
    g_glfw_ok = glfwInit() == GLFW_TRUE;
  });
  if (!g_glfw_ok)
    return make_error(ErrorCode::kUnsupported,
                      "cannot initialise GLFW (no display? run under xvfb-run, or set DISPLAY)");
  glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  GLFWwindow* w = glfwCreateWindow(std::max(1, width), std::max(1, height), title.c_str(), nullptr, nullptr);
  if (!w) return make_error(ErrorCode::kUnsupported, "cannot create an OpenGL 3.3 core context");
  auto ctx = std::unique_ptr<Context>(new Context());
  ctx->window_ = w;
  ctx->make_current();
  return ctx;
}

Context::~Context() {
  if (window_) glfwDestroyWindow(window_);
}

void Context::make_current() { glfwMakeContextCurrent(window_); }

std::string Context::renderer() const {
  const auto* s = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return s ? s : "unknown";
}

}  // namespace vdrig::gl

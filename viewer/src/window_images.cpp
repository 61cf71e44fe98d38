#include "window_images.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "vdrig/gl/program.hpp"

namespace vdrig::viewer {

ImageQuad::ImageQuad() {
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

ImageQuad::~ImageQuad() {
  glDeleteTextures(1, &texture_);
  glDeleteVertexArrays(1, &vao_);
  glDeleteProgram(program_);
}

void ImageQuad::draw(const cv::Mat& bgr, const cv::Rect& rect, int fb_height) {
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

cv::Rect letterbox(const CameraModel& camera, int fb_w, int fb_h) {
  const double s = std::min(static_cast<double>(fb_w) / camera.width, static_cast<double>(fb_h) / camera.height);
  const int w = std::max(1, static_cast<int>(std::lround(camera.width * s)));
  const int h = std::max(1, static_cast<int>(std::lround(camera.height * s)));
  return {(fb_w - w) / 2, (fb_h - h) / 2, w, h};
}

cv::Mat hud_strip(const std::string& line, int width) {
  cv::Mat strip(22, std::max(1, width), CV_8UC3, cv::Scalar(25, 25, 25));
  cv::putText(strip, line, cv::Point(6, 16), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(235, 235, 235), 1, cv::LINE_AA);
  return strip;
}

}  // namespace vdrig::viewer

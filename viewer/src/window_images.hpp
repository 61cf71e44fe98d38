// Images into and out of the interactive viewer's window: the quad that draws photographs, difference images, the
// heads-up strip and the inspector plot; where a camera image sits in a resized window; the heads-up strip itself;
// the back buffer read back for screenshots and scripted frames. Needs the window's OpenGL context current.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::viewer {

/// Draws an 8-bit BGR image into a rectangle of the default framebuffer: the photograph, the difference image, the
/// heads-up line and the inspector plot.
class ImageQuad {
 public:
  ImageQuad();
  ~ImageQuad();
  ImageQuad(const ImageQuad&) = delete;
  ImageQuad& operator=(const ImageQuad&) = delete;

  /// `rect` in framebuffer pixels, (0, 0) = top left.
  void draw(const cv::Mat& bgr, const cv::Rect& rect, int fb_height);

 private:
  unsigned program_ = 0, vao_ = 0, texture_ = 0;
};

/// The framebuffer rectangle a camera image fills when scaled to fit (fit_camera's letterbox).
cv::Rect letterbox(const CameraModel& camera, int fb_w, int fb_h);

/// The heads-up line as an image strip `width` pixels wide.
cv::Mat hud_strip(const std::string& line, int width);

/// The back buffer as CV_8UC3 BGR, OpenCV row order (row 0 at the top).
Result<cv::Mat> read_back_buffer(int width, int height);

/// The first dir/vdrig_view_NNN.png that does not exist yet.
std::filesystem::path next_screenshot_path(const std::filesystem::path& dir);

}  // namespace vdrig::viewer

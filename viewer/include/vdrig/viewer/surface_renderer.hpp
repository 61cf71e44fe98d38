// OpenGL rendering of a ParameterMap: the surface seen from any camera (intrinsics with distortion, pose), with the
// view-dependent model evaluated per fragment by the GLSL the map's model provides (ReflectanceModel::glsl). The
// same shader serves the interactive viewer and the headless render that is compared against the photographs.
//
// How a pixel is shaded: the fragment shader casts the pixel's ray exactly as the simulator does (OpenCV pixel
// centre, distortion removed by fixed-point iteration, samples_per_axis^2 stratified sub-samples), intersects the
// surface plane z = 0, and blends the model's radiance evaluated at the four nearest texels (bilinear in radiance,
// not in parameters: interpolating a lobe direction or an exponent would blur the highlight).
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/gl/context.hpp"

namespace vdrig::viewer {

/// The OpenGL context every render needs (gl/context.hpp: the one GLFW/GL setup, shared with probe_gl).
using GlContext = gl::Context;

struct RenderSettings {
  int samples_per_axis = 2;  // antialiasing, as the simulator
};

class SurfaceRenderer {
 public:
  /// Compiles the shader for the map's model and uploads its channels. The context must be current. kInternal when
  /// the driver rejects the shader or the upload.
  static Result<std::unique_ptr<SurfaceRenderer>> create(const fitting::ParameterMap& map);
  ~SurfaceRenderer();

  /// Renders linear radiance (CV_32FC3, BGR) into an offscreen float framebuffer and reads it back.
  Result<cv::Mat> render_radiance(const CameraModel& camera, const ViewPose& pose, const RenderSettings& settings);
  /// Draws into the current default framebuffer (interactive viewer), tone mapped with y = 1 - exp(-gamma x).
  void draw_tone_mapped(const CameraModel& camera, const ViewPose& pose, const RenderSettings& settings, double gamma);

 private:
  SurfaceRenderer() = default;
  void draw(const CameraModel& camera, const ViewPose& pose, const RenderSettings& settings, int mode, double gamma);
  unsigned program_ = 0, vao_ = 0, params_tex_ = 0, fbo_ = 0, colour_tex_ = 0;
  int fbo_w_ = 0, fbo_h_ = 0;
  int layers_ = 0;
  int texels_s_ = 0, texels_t_ = 0;
  double width_mm_ = 0, height_mm_ = 0;
};

/// Display tone mapping: y = 1 - exp(-gamma x) per channel, then sRGB encoding, 8-bit (BGR in, BGR out).
cv::Mat tone_map(const cv::Mat& radiance_bgr, double gamma);

/// What a camera with this response would record: code = response(radiance * exposure_s * gain), rounded and
/// clipped (CV_8UC3 or CV_16UC3). Used to compare renders with photographs in the camera's own units.
cv::Mat to_camera_codes(const cv::Mat& radiance_bgr, double exposure_s, double gain, const ResponseCurve& response);

/// The GLSL of the map's model as the surface shader compiles it: `vec4 g_params[L]`, `void load_params(ivec2 t)`
/// (reads the L RGBA layers of `uniform sampler2DArray u_params`, channel c in layer c/4) and the model's own
/// `vec3 model(ivec2 t, vec3 v)` (ReflectanceModel::glsl).
std::string model_glsl(const fitting::ParameterMap& map);

/// The surface shader's body, without version line, output or main (GLSL 3.30 core and GLSL ES 3.00 alike): its
/// camera and surface uniforms, the distortion, model_glsl(map), `vec3 pixel_radiance(float px, float py)` (linear
/// radiance of an OpenCV pixel) and `vec3 display_srgb(vec3 radiance)` (tone_map()'s curve). SurfaceRenderer compiles
/// it, and so does the web console's WebGL2 viewer (pipeline::web_scene's "glsl"), each with its own main.
std::string surface_glsl(const fitting::ParameterMap& map);

}  // namespace vdrig::viewer

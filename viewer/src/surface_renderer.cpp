#include "vdrig/viewer/surface_renderer.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/log.hpp"
#include "vdrig/gl/program.hpp"

namespace vdrig::viewer {
namespace {

// The shader's body without its version line, shared with the web console's WebGL2 viewer (surface_glsl()): valid
// GLSL 3.30 core and GLSL ES 3.00 alike. The model's evaluation, `vec3 model(ivec2 t, vec3 v)`, comes between head
// and tail (model_glsl()), after `vec4 g_params[L]`: the texel's parameter layers, fetched once per texel by
// load_params (the model reads its parameters from there; fetching per parameter made texture fetches most of a
// fragment's cost on llvmpipe).
const char* kSurfaceHead = R"(uniform sampler2DArray u_params;   // parameter map channels, 4 per layer
uniform ivec2 u_texels;            // S, T
uniform vec2 u_size_mm;            // W, H
uniform vec4 u_intrinsics;         // fx, fy, cx, cy
uniform float u_dist[5];           // k1, k2, p1, p2, k3
uniform mat3 u_cam_to_surface;     // R^T
uniform vec3 u_centre;             // camera centre, surface frame (mm)
uniform int u_samples;             // sub-samples per axis
uniform int u_height;              // framebuffer height (OpenCV y = row from the top)
uniform float u_gamma;

vec2 distort(vec2 u) {
  float r2 = dot(u, u);
  float radial = 1.0 + r2 * (u_dist[0] + r2 * (u_dist[1] + r2 * u_dist[4]));
  return vec2(u.x * radial + 2.0 * u_dist[2] * u.x * u.y + u_dist[3] * (r2 + 2.0 * u.x * u.x),
              u.y * radial + u_dist[2] * (r2 + 2.0 * u.y * u.y) + 2.0 * u_dist[3] * u.x * u.y);
}
vec2 undistort(vec2 d) {
  // Fixed-point iteration, stopped once converged (at once without distortion): most of a Phong fragment's cost
  // otherwise.
  vec2 u = d;
  for (int i = 0; i < 40; ++i) {
    vec2 step = distort(u) - d;
    u -= step;
    if (dot(step, step) < 1e-16) break;
  }
  return u;
}
)";

const char* kSurfaceTail = R"(
vec3 shade_point(vec3 p) {
  // Bilinear blend of the model evaluated at the four nearest texel centres.
  vec2 st = vec2((p.x + 0.5 * u_size_mm.x) / u_size_mm.x * float(u_texels.x) - 0.5,
                 (p.y + 0.5 * u_size_mm.y) / u_size_mm.y * float(u_texels.y) - 0.5);
  ivec2 t0 = ivec2(floor(st));
  vec2 f = st - vec2(t0);
  vec3 sum = vec3(0.0);
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      ivec2 t = clamp(t0 + ivec2(i, j), ivec2(0), u_texels - 1);
      vec2 c = vec2((float(t.x) + 0.5) / float(u_texels.x) * u_size_mm.x - 0.5 * u_size_mm.x,
                    (float(t.y) + 0.5) / float(u_texels.y) * u_size_mm.y - 0.5 * u_size_mm.y);
      vec3 v = normalize(u_centre - vec3(c, 0.0));
      float w = (i == 1 ? f.x : 1.0 - f.x) * (j == 1 ? f.y : 1.0 - f.y);
      load_params(t);
      sum += w * model(t, v);
    }
  return sum;
}

// Linear radiance of camera pixel (px, py) (OpenCV: centre of pixel 0 at 0, y = row from the top): the mean of
// u_samples^2 stratified sub-pixel rays onto the surface plane; a ray that misses the surface adds nothing.
vec3 pixel_radiance(float px, float py) {
  vec3 sum = vec3(0.0);
  float n = float(u_samples);
  for (int sy = 0; sy < u_samples; ++sy)
    for (int sx = 0; sx < u_samples; ++sx) {
      vec2 pix = vec2(px - 0.5 + (float(sx) + 0.5) / n, py - 0.5 + (float(sy) + 0.5) / n);
      vec2 u = undistort(vec2((pix.x - u_intrinsics.z) / u_intrinsics.x, (pix.y - u_intrinsics.w) / u_intrinsics.y));
      vec3 ray = u_cam_to_surface * normalize(vec3(u, 1.0));
      if (abs(ray.z) < 1e-9) continue;
      float s = -u_centre.z / ray.z;
      if (s <= 0.0) continue;
      vec3 p = u_centre + s * ray;
      if (abs(p.x) > 0.5 * u_size_mm.x || abs(p.y) > 0.5 * u_size_mm.y) continue;
      sum += shade_point(vec3(p.xy, 0.0));
    }
  return sum / (n * n);
}

// Display tone mapping (tone_map()'s): y = 1 - exp(-gamma x), then sRGB encoding.
vec3 display_srgb(vec3 radiance) {
  vec3 y = 1.0 - exp(-u_gamma * max(radiance, vec3(0.0)));
  return mix(12.92 * y, 1.055 * pow(y, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), y));
}
)";

// The desktop shader: surface_glsl() with its output and main.
const char* kDesktopHead = R"(#version 330 core
out vec4 out_colour;
uniform int u_mode;                // 0 = linear radiance, 1 = tone mapped sRGB
uniform bool u_flip_y;             // default framebuffer: row 0 at the bottom
)";

const char* kDesktopMain = R"(
void main() {
  float px = gl_FragCoord.x - 0.5;
  float py = u_flip_y ? float(u_height) - gl_FragCoord.y - 0.5 : gl_FragCoord.y - 0.5;
  vec3 radiance = pixel_radiance(px, py);
  out_colour = vec4(u_mode == 0 ? radiance : display_srgb(radiance), 1.0);
}
)";

}  // namespace

// Parameter i is read from the component of g_params that holds its map channel.
std::string model_glsl(const fitting::ParameterMap& map) {
  int layers = 1;
  for (int i = 0; i < map.model().parameter_count(); ++i) layers = std::max(layers, map.parameter_channel(i) / 4 + 1);
  const std::string n = std::to_string(layers);
  return "vec4 g_params[" + n + "];\nvoid load_params(ivec2 t) {\n  for (int l = 0; l < " + n +
         "; ++l) g_params[l] = texelFetch(u_params, ivec3(t, l), 0);\n}\n" + map.model().glsl([&map](int i) {
           const int c = map.parameter_channel(i);
           return std::string("g_params[") + std::to_string(c / 4) + "]." + "xyzw"[c % 4];
         });
}

std::string surface_glsl(const fitting::ParameterMap& map) {
  return std::string(kSurfaceHead) + model_glsl(map) + kSurfaceTail;
}

Result<std::unique_ptr<SurfaceRenderer>> SurfaceRenderer::create(const fitting::ParameterMap& map) {
  auto program = gl::link_program(gl::kFullScreenTriangleVertexShader,
                                  std::string(kDesktopHead) + surface_glsl(map) + kDesktopMain, "surface shader");
  if (!program) return program.error();
  auto r = std::unique_ptr<SurfaceRenderer>(new SurfaceRenderer());
  r->program_ = program.value();
  glGenVertexArrays(1, &r->vao_);
  r->texels_s_ = map.texels_s();
  r->texels_t_ = map.texels_t();
  r->width_mm_ = map.width_mm();
  r->height_mm_ = map.height_mm();

  // Upload every channel: layer l holds channels 4l..4l+3 as RGBA32F.
  const auto& img = map.image();
  const int C = static_cast<int>(img.channels.size());
  r->layers_ = (C + 3) / 4;
  std::vector<float> data(static_cast<size_t>(r->layers_) * img.width * img.height * 4, 0.0f);
  for (int c = 0; c < C; ++c) {
    const int layer = c / 4, comp = c % 4;
    for (int y = 0; y < img.height; ++y) {
      const float* row = img.channels[c].ptr<float>(y);
      for (int x = 0; x < img.width; ++x)
        data[((static_cast<size_t>(layer) * img.height + y) * img.width + x) * 4 + comp] = row[x];
    }
  }
  glGenTextures(1, &r->params_tex_);
  glBindTexture(GL_TEXTURE_2D_ARRAY, r->params_tex_);
  glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA32F, img.width, img.height, r->layers_, 0, GL_RGBA, GL_FLOAT,
               data.data());
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  if (glGetError() != GL_NO_ERROR) return make_error(ErrorCode::kInternal, "uploading the parameter map failed");
  return r;
}

SurfaceRenderer::~SurfaceRenderer() {
  if (fbo_) glDeleteFramebuffers(1, &fbo_);
  if (colour_tex_) glDeleteTextures(1, &colour_tex_);
  if (params_tex_) glDeleteTextures(1, &params_tex_);
  if (vao_) glDeleteVertexArrays(1, &vao_);
  if (program_) glDeleteProgram(program_);
}

void SurfaceRenderer::draw(const CameraModel& cam, const ViewPose& pose, const RenderSettings& settings, int mode,
                           double gamma) {
  glUseProgram(program_);
  auto loc = [&](const char* n) { return glGetUniformLocation(program_, n); };
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D_ARRAY, params_tex_);
  glUniform1i(loc("u_params"), 0);
  glUniform2i(loc("u_texels"), texels_s_, texels_t_);
  glUniform2f(loc("u_size_mm"), static_cast<float>(width_mm_), static_cast<float>(height_mm_));
  glUniform4f(loc("u_intrinsics"), static_cast<float>(cam.fx), static_cast<float>(cam.fy), static_cast<float>(cam.cx),
              static_cast<float>(cam.cy));
  const float dist[5] = {static_cast<float>(cam.k1), static_cast<float>(cam.k2), static_cast<float>(cam.p1),
                         static_cast<float>(cam.p2), static_cast<float>(cam.k3)};
  glUniform1fv(loc("u_dist"), 5, dist);
  // GLSL mat3 is column-major: column j holds (R^T)(:, j) = R(j, :).
  float m[9];
  const Mat3d Rt = pose.R.transpose();
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) m[j * 3 + i] = static_cast<float>(Rt(i, j));
  glUniformMatrix3fv(loc("u_cam_to_surface"), 1, GL_FALSE, m);
  const Vec3d c = pose.camera_centre();
  glUniform3f(loc("u_centre"), static_cast<float>(c.x()), static_cast<float>(c.y()), static_cast<float>(c.z()));
  glUniform1i(loc("u_samples"), settings.samples_per_axis);
  glUniform1i(loc("u_height"), cam.height);
  glUniform1i(loc("u_mode"), mode);
  glUniform1f(loc("u_gamma"), static_cast<float>(gamma));
  glUniform1i(loc("u_flip_y"), mode == 1 ? 1 : 0);
  glBindVertexArray(vao_);
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

Result<cv::Mat> SurfaceRenderer::render_radiance(const CameraModel& cam, const ViewPose& pose,
                                                 const RenderSettings& settings) {
  if (fbo_w_ != cam.width || fbo_h_ != cam.height) {
    if (fbo_) glDeleteFramebuffers(1, &fbo_);
    if (colour_tex_) glDeleteTextures(1, &colour_tex_);
    glGenTextures(1, &colour_tex_);
    glBindTexture(GL_TEXTURE_2D, colour_tex_);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, cam.width, cam.height, 0, GL_RGBA, GL_FLOAT, nullptr);
    glGenFramebuffers(1, &fbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, colour_tex_, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      return make_error(ErrorCode::kUnsupported, "float framebuffer not supported by this OpenGL driver");
    fbo_w_ = cam.width;
    fbo_h_ = cam.height;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glViewport(0, 0, cam.width, cam.height);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  draw(cam, pose, settings, 0, 1.0);
  cv::Mat rgba(cam.height, cam.width, CV_32FC4);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  // Framebuffer row r holds OpenCV row r (the shader maps gl_FragCoord.y straight to the pixel row).
  glReadPixels(0, 0, cam.width, cam.height, GL_RGBA, GL_FLOAT, rgba.data);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (const GLenum e = glGetError(); e != GL_NO_ERROR)
    return make_error(ErrorCode::kInternal, "OpenGL error " + std::to_string(e) + " while rendering");
  cv::Mat bgr;
  cv::cvtColor(rgba, bgr, cv::COLOR_RGBA2BGR);
  return bgr;
}

void SurfaceRenderer::draw_tone_mapped(const CameraModel& cam, const ViewPose& pose, const RenderSettings& settings,
                                       double gamma) {
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glClearColor(0.05f, 0.05f, 0.06f, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  draw(cam, pose, settings, 1, gamma);
}

cv::Mat tone_map(const cv::Mat& radiance, double gamma) {
  VDRIG_CHECK(radiance.type() == CV_32FC3, "tone_map needs CV_32FC3");
  cv::Mat out(radiance.size(), CV_8UC3);
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const cv::Vec3f v = radiance.at<cv::Vec3f>(y, x);
      cv::Vec3b o;
      for (int c = 0; c < 3; ++c) {
        const double t = 1.0 - std::exp(-gamma * std::max(0.0f, v[c]));
        const double s = t <= 0.0031308 ? 12.92 * t : 1.055 * std::pow(t, 1.0 / 2.4) - 0.055;
        o[c] = cv::saturate_cast<uchar>(std::round(s * 255.0));
      }
      out.at<cv::Vec3b>(y, x) = o;
    }
  return out;
}

cv::Mat to_camera_codes(const cv::Mat& radiance, double exposure_s, double gain, const ResponseCurve& response) {
  VDRIG_CHECK(radiance.type() == CV_32FC3, "to_camera_codes needs CV_32FC3");
  const int depth = response.bits() <= 8 ? CV_8U : CV_16U;
  cv::Mat out(radiance.size(), CV_MAKETYPE(depth, 3));
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const cv::Vec3f v = radiance.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) {
        const double code = std::round(response.forward(2 - c, v[c] * exposure_s * gain));
        if (depth == CV_8U)
          out.at<cv::Vec3b>(y, x)[c] = static_cast<uchar>(code);
        else
          out.at<cv::Vec3w>(y, x)[c] = static_cast<uint16_t>(code);
      }
    }
  return out;
}

}  // namespace vdrig::viewer

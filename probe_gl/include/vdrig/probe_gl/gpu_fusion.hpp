// GPU fusion of light probes (docs/probe.md, "GPU fusion"): the probe fused at a moving object's position, every
// frame, as a world-aligned cube map rendered by OpenGL from the proxy room and the source probes, with the weights
// and the depth visibility of the CPU fusion (probe/fusion.hpp; probe::fuse_cube is the reference this matches).
//
// Why a module of its own: `probe` has no OpenGL dependency (its tests and the CLI's non-GL commands run without a
// display), and the viewer renders parameter maps. probe_gl takes gl::Context (gl/context.hpp: the project's one
// GLFW/GL setup, the viewer's too) and probe's data types, and adds only the fusion shader.
//
// How: one draw of a full-screen triangle into a 6 N x N RGBA32F framebuffer, the six faces side by side in
// CubeFace order (+x -x +y -y +z -z, cube_map.hpp's convention). Per texel the fragment shader casts the centre ray
// from the position to the box, and for every source probe (a layer of one RGBA32F 2D-array texture: radiance in
// RGB, proxy depth in A) evaluates reproject()'s weight: source behind the wall, minimum distance, visibility against
// the largest depth of the four nearest source pixels, ((1 + w.w_i) / 2)^P, min(1, rho)^Q; the source's radiance by
// the same bilinear look-up as probe::radiance_at (four texel fetches, wrapping in azimuth, clamped in zenith).
// Texels no probe sees get the nearest probe's radiance along the ray (fuse()'s fallback). Arithmetic is float.
#pragma once

#include <memory>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/probe.hpp"

namespace vdrig::probe_gl {

class GpuFusion {
 public:
  /// Source probes per draw (uniform arrays in the shader).
  static constexpr int kMaxProbes = 8;

  /// Uploads the probes and compiles the shader; an OpenGL 3.3 context (gl::Context) must be current and stay
  /// current while this object is used. Errors: kInvalidArgument for what probe::validate_fusion_inputs rejects,
  /// more than kMaxProbes probes or cube_size outside [1, 2048]; kInternal when the driver rejects the shader or a
  /// texture; kUnsupported without float render targets.
  static Result<std::unique_ptr<GpuFusion>> create(const std::vector<probe::Probe>& probes, const probe::ProxyBox& room,
                                                   int cube_size, const probe::FusionOptions& options = {});
  ~GpuFusion();
  GpuFusion(const GpuFusion&) = delete;
  GpuFusion& operator=(const GpuFusion&) = delete;

  /// Draws the cube fused at position_mm into the GPU framebuffer and flushes (returns once the commands are
  /// submitted, so the caller can work on the previous frame's lights meanwhile).
  /// kInvalidArgument when the position is not strictly inside the room.
  Status render(const Vec3d& position_mm);
  /// Waits until the queued draw has finished (glFinish), for timing the fusion apart from the read-back.
  void finish();
  /// Reads the last render back (waits for the GPU): the cube in the world frame, B, G, R texels as CubeMap's.
  /// kInternal on an OpenGL error.
  Result<probe::CubeMap> read_back();
  /// render(), then read_back().
  Result<probe::CubeMap> fuse(const Vec3d& position_mm);

  int cube_size() const { return size_; }

 private:
  GpuFusion() = default;
  unsigned program_ = 0, vao_ = 0, probes_tex_ = 0, fbo_ = 0, colour_tex_ = 0;
  int size_ = 0;
  probe::ProxyBox room_;
  std::vector<Vec3d> positions_;  // the probes' centres, for the fallback's nearest probe
  bool rendered_ = false;
};

}  // namespace vdrig::probe_gl

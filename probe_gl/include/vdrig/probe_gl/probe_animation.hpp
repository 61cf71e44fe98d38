// `vdrig probe animate` as a library call (docs/probe.md, "Animation"): a room file (the box and its probes) and a
// path file in, PNG frames and frames.json out. Per frame the probes are fused on the GPU (GpuFusion) at the
// object's position, turned into soft lights (probe/soft_lights.hpp) and the scene rendered on the CPU
// (probe/animation.hpp): a diffuse sphere on the path and a glossy one beside it, with shadows on the floor.
//
// Everything is checked (settings, room, probes, path inside the room for both spheres, camera, OpenGL) before the
// first frame is written. The MP4 is not made here: probe/video.hpp encodes the frames.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::probe_gl {

struct ProbeAnimationSettings {
  std::filesystem::path room_file;  // vdrig.probe.room: the box and the probes (relative files: beside it)
  std::filesystem::path path_file;  // vdrig.probe.path: keys of time_s and position_mm
  std::filesystem::path out_dir;    // frame_NNNN.png and frames.json (created when missing)
  int frames = 120;                 // evenly spaced in time over the path
  int soft_lights = 64;             // soft:N lights per frame
  int width = 640, height = 360;    // frame size, pixels
  int cube_size = 128;              // face size of the fused cube
  int shrink = 8;                   // the cube is shrunk by this factor for the lights (cube_size a multiple of it)
  double sphere_radius_mm = 150;    // also the path's margin from the walls
  int shadow_lights = 4;            // strongest lights casting shadows on the ground
  int samples_per_axis = 2;         // antialiasing rays per pixel and axis
  std::optional<Vec3d> camera_mm;   // unset: probe::frame_path's camera
  std::optional<Vec3d> look_at_mm;  // unset: probe::frame_path's
  double fov_deg = 50;              // horizontal field of view
  double gamma = 0;                 // tone mapping y = 1 - exp(-gamma x); 0: from frame 0, then fixed
  bool design_notes = false;        // probe files without vdrig attributes already run with vdrig's azimuth
};

/// What was written, and where the time went (milliseconds per frame).
struct ProbeAnimationResult {
  int frames = 0;
  double gamma = 0;  // the tone mapping used for every frame
  double fuse_ms = 0, lights_ms = 0, render_ms = 0;
};

/// Renders the frames. Errors: kInvalidArgument for settings out of range (naming the field), a path that leaves the
/// room (either sphere), a camera that is not valid; the errors of the room, path and probe files (each naming its
/// file); kUnsupported/kInternal when OpenGL 3.3 is not available; kIo/kNoSpace when writing.
Result<ProbeAnimationResult> render_probe_animation(const ProbeAnimationSettings& settings);

}  // namespace vdrig::probe_gl

// Blender as an independent renderer (docs/blender.md): a long-lived `blender --background --factory-startup` process
// running vdrig's driver script (sim/blender/vdrig_blender.py, compiled into the library), driven over a socket on
// its stdin and fd 3, renders a vdrig scene (or a user's .blend) with Cycles on the CPU and returns linear radiance
// in vdrig's units (a white Lambertian surface at d mm from a light of intensity I: I / d^2). The "blender" camera
// backend (rig config "camera": {"backend": "blender", ...}) puts the simulator's sensor model (exposure, noise,
// response, quantisation: sim::expose) behind it, so the rest of the chain sees an ordinary camera.
//
// Camera section settings (all optional; unknown keys rejected), beside the rig config's shared "sim" section that
// gives the scene, the camera's intrinsics and sensor, and the rig's true geometry as for the "sim" camera:
//   { "backend": "blender", "executable": "blender", "samples": 16 (Cycles samples a pixel, 1..4096),
//     "seed": 1 (Cycles' seed: a view renders the same twice), "threads": 2, "timeout_s": 120 (one render),
//     "startup_timeout_s": 60, "blend": "" (a .blend whose mesh "surface" is the sample, docs/blender.md),
//     "markers": true (with "blend": vdrig's corner markers on the surface) }
// Errors: Blender missing kNotFound; a bad scene or .blend kInvalidArgument; Blender exiting kDevice (with the end of
// its log); no answer in time kTimeout (the process is killed). After kDevice or kTimeout the next call starts a new
// Blender process, so a capture resumes as after any camera fault.
#pragma once

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {

struct BlenderSettings {
  std::string executable = "blender";
  int samples = 16;
  uint64_t seed = 1;
  int threads = 2;
  double timeout_s = 120.0;
  double startup_timeout_s = 60.0;
  std::string blend;
  bool markers = true;

  /// The camera section ("backend" allowed); every problem reported at once.
  static Result<BlenderSettings> parse(const nlohmann::json& section);
  nlohmann::json effective() const;
};

/// One Blender process. Not thread-safe (a camera owns one).
class BlenderRenderer {
 public:
  explicit BlenderRenderer(BlenderSettings settings);
  ~BlenderRenderer();
  BlenderRenderer(const BlenderRenderer&) = delete;
  BlenderRenderer& operator=(const BlenderRenderer&) = delete;

  /// What later renders show: the scene (ignored but for its markers when settings.blend is set) seen by `camera`.
  /// Lens distortion is applied by resampling a larger pinhole render (Blender's camera has none). Starts Blender
  /// when it is not running (kNotFound when the executable is missing).
  Status set_scene(const Scene& scene, const CameraModel& camera);
  /// Linear radiance (CV_32FC3, BGR) at `pose`; `lights` false renders with every light and the world off.
  Result<cv::Mat> render(const ViewPose& pose, bool lights = true);
  /// Seconds Blender took to start (last start) and to render the last view.
  double startup_s() const { return startup_s_; }
  double last_render_s() const { return last_render_s_; }
  /// Test hooks: make the running Blender exit, or stop answering, at its next command.
  Status inject(const std::string& what);

 private:
  Status ensure_running();
  Status setup();
  Result<nlohmann::json> request(const nlohmann::json& command, double timeout_s);
  void stop(bool kill_now);
  std::string log_tail() const;

  BlenderSettings settings_;
  std::filesystem::path dir_;
  int socket_ = -1;
  int pid_ = -1;
  std::string buffer_;
  bool configured_ = false;
  std::unique_ptr<Scene> scene_;
  CameraModel camera_;
  CameraModel pinhole_;  // what Blender renders (the camera without distortion, with a margin when distorted)
  cv::Mat map_x_, map_y_;
  double startup_s_ = 0, last_render_s_ = 0;
  uint64_t renders_ = 0;
};

}  // namespace vdrig::sim

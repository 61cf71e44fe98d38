// The simulated rig: a PanTiltStage, a Camera and a Light behind the same interfaces as the hardware, sharing one
// SimWorld (the platform's pose, the scene on it, the fixed camera). It is the default backend ("sim").
//
// The simulated devices' own sections hold only "backend" ("stage": {"backend": "sim"}); what they simulate is in
// the rig config's shared section "sim" (edges in degrees, mm, seconds); every key is optional, unknown keys are
// rejected:
//   { "scene": "patchwork", "distance_mm": 2500, "surface_offset_mm": [0, 0, 0],
//     "pan_zero_deg": 0, "tilt_zero_deg": 0, "pan_axis_tilt_deg": [0, 0] (an imperfect rig, rig/kinematics.hpp: the
//     stage reports encoder readings, the platform turns by the true angles), "samples_per_axis": 2,
//     "time_scale": 0 (0 = moves take no wall time, 1 = real time), "seed": 1,
//     "state_file": "" (a file where the stage keeps its position between processes, as a real drive does; empty:
//                       every rig built from the config starts at 0, 0),
//     "camera": { "width": 640, "height": 480, "fx": 800, "fy": 800, "cx": 319.5, "cy": 239.5,
//                 "k1": -0.08, "k2": 0.02, "p1": 0, "p2": 0, "k3": 0, "bits": 8,
//                 "response": "s-curve" | "linear", "full_well_e": 20000, "read_noise_e": 8, "vignetting": 0,
//                 "noise_seed": "sequence" | "shot" (see SimConfig::noise_by_shot) },
//     "stage": { "pan_min_deg": -360, "pan_max_deg": 360, "tilt_min_deg": -5, "tilt_max_deg": 85,
//                "speed_deg_s": 30, "accel_deg_s2": 60 },
//     "faults": { see SimFaults } }
#pragma once

#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <vector>

#include "vdrig/rig/kinematics.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {

/// The simulated camera's sensor noise unless the config says otherwise ("full_well_e": 0 turns photon and read noise
/// off): a small sensor's well, and read noise of a tenth of a code at 8 bits.
inline constexpr double kDefaultFullWellE = 20000.0;
inline constexpr double kDefaultReadNoiseE = 8.0;

/// Injected device faults, for capture's recovery tests. Deterministic: each list holds 1-based call numbers of
/// the device call that fails (the 3rd move_to is 3; home() is not counted as a move). What a failure does:
///  - move_timeout_at (stage.move_to): kTimeout; the platform stopped half way (position() reads it back);
///  - drive_error_at (stage.move_to): kDevice (drive alarm); the platform did not move;
///  - drop_frame_at (camera.capture): kTimeout (no frame arrived); the frame counter still advances, so the next
///    frame's sequence shows the gap as on a real camera;
///  - disconnect_camera_at (camera.capture): kDisconnected from that call on, for every camera call (info,
///    set_exposure, capture), for disconnect_calls calls (0 = until the rig is built again);
///  - slow_write_ms: every stage command and set_exposure takes this much longer (wall time, not time-scaled).
struct SimFaults {
  std::vector<uint64_t> move_timeout_at;
  std::vector<uint64_t> drive_error_at;
  std::vector<uint64_t> drop_frame_at;
  std::vector<uint64_t> disconnect_camera_at;
  uint64_t disconnect_calls = 0;
  double slow_write_ms = 0.0;

  bool any() const;
};

struct SimConfig {
  /// Largest simulated image side, pixels ("camera" width and height): a frame, its radiance and the ray table
  /// (samples_per_axis^2 rays a pixel) must fit in memory; at 4096 x 4096 and 2 samples a side that is about 1.5 GB.
  static constexpr int kMaxCameraSide = 4096;
  std::string scene = "patchwork";
  CameraModel camera{640, 480, 800.0, 800.0, 319.5, 239.5, -0.08, 0.02, 0.0, 0.0, 0.0};
  SensorSettings sensor;
  rig::RigGeometry geometry;
  rig::StageSpec stage;
  SimFaults faults;
  int samples_per_axis = 2;
  double time_scale = 0.0;
  /// Where the simulated stage keeps its position and homed flag between processes (JSON, written atomically after
  /// every move and home, read when the rig is built), as a real drive's encoders keep theirs: `vdrig rig move` and
  /// then `vdrig rig position` read the same position. Empty: not kept, each built rig starts at 0, 0.
  std::string state_file;
  /// camera "noise_seed": "shot" seeds each frame's sensor noise by what is shot (seed, stage position, exposure,
  /// gain, light) instead of the process's frame counter ("sequence", the default): a frame shot again, or in another
  /// process (a resumed capture), is bit-identical. Identical shots then have identical noise (a real camera's do not).
  bool noise_by_shot = false;

  SimConfig();
  /// Reads the "sim" section; unknown keys are rejected so a typo does not silently fall back to a default.
  static Result<SimConfig> from_json(const nlohmann::json& section);
  bool is_valid(std::string* why) const;
};

/// State shared by the simulated devices of one rig.
struct SimWorld {
  SimConfig config;
  Scene scene;
  std::mutex mutex;
  PanTilt position;  // current platform position
  bool homed = false;
  uint64_t frame_sequence = 0;
  double exposure_s = 0.01;
  double gain = 1.0;
  bool light_on = true;
  double motion_time_s = 0.0;         // simulated time spent moving so far (unscaled; also counted when time_scale = 0)
  uint64_t move_calls = 0;            // stage.move_to calls so far (fault counters)
  uint64_t capture_calls = 0;         // camera.capture calls so far
  uint64_t disconnected_at_call = 0;  // capture call number at which the camera went away (0 = connected)
  uint64_t camera_calls_while_disconnected = 0;
  std::shared_ptr<const RayTable> rays;  // per-camera ray table, built at the first capture

  ViewPose pose() const { return rig::surface_pose(config.geometry, position); }
  /// What seeds the noise of the frame shot now with this `sequence` (config.noise_by_shot). Caller holds the mutex.
  uint64_t noise_key(uint64_t sequence) const;
};

/// What the simulated `kind` ("stage", "camera", "light") declares to the registry: it reads the shared "sim"
/// section, and its own section holds only "backend" (any other key is rejected, naming it).
rig::BackendSpec backend_spec(const std::string& kind);

/// Adds the "sim" stage, camera and light backends, and the shared "sim" section (validated by SimConfig::from_json).
void register_backends(rig::BackendRegistry& registry);

/// A registry of every rig backend of this build: the simulator's ("sim") beside the hardware compiled into rig
/// (rig::register_hardware_backends). What builds rigs that may be simulated uses it: the executables built with
/// the simulator (apps/rig_backends/), the pipeline's reference sessions, the tests.
rig::BackendRegistry simulator_and_hardware_backends();

/// A rig config that selects the simulator for every device, with the given "sim" section.
nlohmann::json sim_rig_config(const nlohmann::json& sim_section = nlohmann::json::object());

}  // namespace vdrig::sim

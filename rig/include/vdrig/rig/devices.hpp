// The rig's device interfaces: one small interface per device kind. capture/ sees only these; every
// technology (Modbus drive, step/dir over GPIO, V4L2, libcamera, the simulator) is one backend behind them.
//
// All calls may block; none may throw for a device failure: they return Status/Result (see core/result.hpp).
// Angles are radians inside vdrig (degrees only in config files, CLI and JSON).
#pragma once

#include <memory>
#include <string>

#include "vdrig/core/frame.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/stage_spec.hpp"  // AxisSpec, StageSpec (the hardware-free rig model)

namespace vdrig::rig {

/// A two-axis turntable: pan about the surface normal, tilt about a horizontal axis.
class PanTiltStage {
 public:
  virtual ~PanTiltStage() = default;
  virtual std::string backend() const = 0;
  virtual StageSpec spec() const = 0;
  /// Wall-clock seconds a move takes per second of its speed profile (spec()): 1 for a real drive; a simulated stage
  /// runs faster (its time_scale, 0 = instant). The self-test times moves against the profile scaled by it.
  virtual double wall_time_scale() const { return 1.0; }
  /// Drives both axes to their reference (limit/index) and sets the position to zero.
  virtual Status home() = 0;
  /// Moves both axes at once and returns when both are in position (or with kTimeout / kDevice).
  virtual Status move_to(const PanTilt& target) = 0;
  /// Position read back from the drives' encoders (or step counters).
  virtual Result<PanTilt> position() = 0;
  /// Stops any motion at once (decelerating where the drive allows). May be called from another thread while
  /// home() or move_to() runs; a backend that can, ends that call early (kCancelled) rather than at its timeout.
  virtual Status stop() = 0;
};

/// What a camera can do, reported after open.
struct CameraInfo {
  std::string model;
  int width = 0;
  int height = 0;
  int bits = 8;
  double min_exposure_s = 1e-5;
  double max_exposure_s = 10.0;
  bool auto_exposure_on = false;  // a camera left in auto exposure/gain ruins a bracket: capture warns
};

class Camera {
 public:
  virtual ~Camera() = default;
  virtual std::string backend() const = 0;
  virtual Result<CameraInfo> info() = 0;
  /// Sets exposure time and analogue gain for the next capture; may round to what the sensor supports
  /// (capture() reports the value actually used).
  virtual Status set_exposure(double exposure_s, double gain) = 0;
  /// Takes one photograph with the current settings. kDisconnected when the camera went away.
  virtual Result<Frame> capture() = 0;
};

class Light {
 public:
  virtual ~Light() = default;
  virtual std::string backend() const = 0;
  virtual Status set_on(bool on) = 0;
};

/// A whole rig as capture/ drives it. `light` may be null (a light that is always on).
struct Rig {
  std::unique_ptr<PanTiltStage> stage;
  std::unique_ptr<Camera> camera;
  std::unique_ptr<Light> light;
};

}  // namespace vdrig::rig

// Bring-up of a real rig (`vdrig rig ...`, docs/hardware.md): which devices this machine has, whether a rig config
// is valid and what it means once the defaults are filled in, and a self-test that exercises a built rig end to end.
// The executables only print what these return.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/rig/devices.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {

/// One device found on this machine.
struct FoundDevice {
  std::string path;     // what a rig config names it by: /dev/video0, a libcamera id, usb:BUS:ADDR, /dev/ttyUSB0
  std::string summary;  // driver/model/vendor and what matters for a config (exposure controls, line names)
};

/// Devices of one kind ("V4L2 cameras", "libcamera cameras", "USB PTP still cameras", "serial ports",
/// "GPIO chips"). `note` says why a kind could not be searched (a backend not built, a library error); `devices`
/// empty and `note` empty means searched, none found.
struct DeviceKind {
  std::string kind;
  std::vector<FoundDevice> devices;
  std::string note;
};

/// Looks for every kind of device the hardware backends drive. Never fails: what cannot be searched is a note.
std::vector<DeviceKind> list_devices();

/// What `vdrig rig check` reports about a config, without opening any device.
struct ConfigCheck {
  std::vector<std::string> problems;  // every problem of every section; empty = valid
  nlohmann::json effective;           // per section, the settings as the backend will use them (defaults filled in)
};

/// Validates all of `config` against the backends of `registry`: the top level (BackendRegistry::top_level_problems:
/// unknown keys, "lock", "geometry", the shared sections such as "sim"), then each device section ("stage" and
/// "camera" required, "light" optional) with the settings parser its backend was registered with (BackendSpec::check),
/// so a new backend's section is validated with no change here. Every problem is listed, each naming its key.
ConfigCheck check_rig_config(const nlohmann::json& config, const BackendRegistry& registry);

struct SelfTestOptions {
  double move_deg = 5.0;                                    // size of the small test moves (within the axis limits)
  double position_tolerance_deg = 0.05;                     // read-back after a move
  std::vector<double> exposures_s = {0.002, 0.008, 0.032};  // the short bracket, one frame each
};

struct SelfTestStep {
  std::string name;
  bool passed = false;
  std::string detail;  // measured values, or the error
};

/// Runs on a built rig: home; small moves of each axis, read back within tolerance and timed against the speed
/// profile the stage reports (PanTiltStage::spec); one frame per exposure of a short bracket (brighter with longer
/// exposure until saturated); the light on and off when there is one. Stops at the first failed motion step (later
/// steps would only repeat it). Leaves the stage at its home position when it can.
/// A move that takes less than half its profile time minus 20 ms, or more than three times it plus 1 s, fails: the
/// drive then got other numbers than sent. The profile time is scaled by PanTiltStage::wall_time_scale (the
/// simulator's time_scale: its moves are meant to be faster). Any other stage whose moves are instant (a stand-in, an
/// emulator) passes only when its spec says so (very high speed and acceleration), which the route planner, timing
/// routes with the same spec, needs anyway.
std::vector<SelfTestStep> run_self_test(Rig& rig, const SelfTestOptions& options = {});

}  // namespace vdrig::rig

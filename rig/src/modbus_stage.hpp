// modbus-tcp / modbus-rtu pan/tilt stage: two position drives (pan, tilt) on one Modbus link, addressed by their
// unit (slave) id, with the register map of modbus_map.hpp / docs/rig-modbus.md.
//
// Settings (JSON "stage" section; degrees and seconds):
//   modbus-tcp: "host" (required), "port" (502)
//   modbus-rtu: "device" (required, e.g. /dev/ttyUSB0), "baud" (115200), "parity" ("N"|"E"|"O"), "data_bits" (8),
//               "stop_bits" (1)
//   both: "response_timeout_s" (0.2), "retries" (2, extra attempts on transient errors), "poll_interval_s" (0.02),
//         "move_timeout_s" (5; a move may take twice its profile time plus this), "home_timeout_s" (120),
//         "word_order" ("high-first"|"low-first"),
//         "register_base" (0),
//         "pan" / "tilt": { "unit" (1..247, required), "counts_per_degree" (required, != 0; negative flips the
//                           direction), "min_deg", "max_deg", "max_speed_deg_s", "accel_deg_s2",
//                           "continuous" (false), "in_position_window_deg" (0.05) }
// Locks: the stage locks its drive when it first connects, so that one process drives it whatever runtime folder
// each was started with (core/process_lock.hpp): modbus-rtu flocks the opened serial port itself (again after every
// reconnect), modbus-tcp holds a lock file named from host and port in device_lock_dir() for the stage's lifetime.
// Another process's stage on the same drive fails to connect with kInUse naming that process's PID.
// Errors: a drive fault, a refused command or a position outside the move's span (a word-order mismatch) is kDevice
// naming the axis, its position and the drive's codes; no answer within the timeout (after retries) is kTimeout; a
// lost link is kDisconnected and the next call reconnects. Every failure of move_to/home stops both drives.
// "max_speed_deg_s"/"accel_deg_s2" x |counts_per_degree| must fit the uint32 profile registers (validated).
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "modbus_map.hpp"
#include "vdrig/core/process_lock.hpp"
#include "vdrig/rig/devices.hpp"

typedef struct _modbus modbus_t;  // libmodbus stays private to the .cpp

namespace vdrig::rig {

struct ModbusAxisConfig {
  int unit = 1;
  double counts_per_degree = 0.0;
  double in_position_window_deg = 0.05;
  AxisSpec axis;  // radians
};

struct ModbusStageConfig {
  bool rtu = false;
  std::string host;  // TCP
  int port = 502;
  std::string device;  // RTU
  int baud = 115200;
  char parity = 'N';
  int data_bits = 8;
  int stop_bits = 1;
  double response_timeout_s = 0.2;
  int retries = 2;
  double poll_interval_s = 0.02;
  double move_timeout_s = 5.0;  // margin beyond twice the profile time of a move
  double home_timeout_s = 120.0;
  modbus_map::WordOrder word_order = modbus_map::WordOrder::kHighFirst;
  int register_base = 0;
  ModbusAxisConfig pan, tilt;

  /// Parses and validates a "stage" section; kInvalidArgument listing every problem.
  static Result<ModbusStageConfig> parse(const nlohmann::json& settings, bool rtu);
  /// The settings as the backend uses them, defaults filled in, in the section's JSON keys (`vdrig rig check`).
  nlohmann::json effective() const;
};

class ModbusStage final : public PanTiltStage {
 public:
  explicit ModbusStage(ModbusStageConfig config);
  ~ModbusStage() override;
  ModbusStage(const ModbusStage&) = delete;
  ModbusStage& operator=(const ModbusStage&) = delete;

  std::string backend() const override { return config_.rtu ? "modbus-rtu" : "modbus-tcp"; }
  StageSpec spec() const override { return {config_.pan.axis, config_.tilt.axis}; }
  Status home() override;
  Status move_to(const PanTilt& target) override;
  Result<PanTilt> position() override;
  Status stop() override;

  /// Opens the link now (the factory calls it so a wrong address fails early); later calls reconnect on demand.
  Status connect();

 private:
  struct Readback {
    uint16_t command = 0;  // non-zero: a command the drive has not accepted (yet)
    uint16_t status = 0;
    int32_t actual_counts = 0;
    uint16_t fault_code = 0;
  };
  enum class Axis { kPan, kTilt };

  const ModbusAxisConfig& axis(Axis a) const { return a == Axis::kPan ? config_.pan : config_.tilt; }
  const char* name(Axis a) const { return a == Axis::kPan ? "pan" : "tilt"; }
  Status ensure_connected();
  void drop_connection(const char* why);
  /// After a failed request: makes sure its answer, should it still come, is never read as the answer to a later
  /// request (TCP: a new connection, opened now when `reconnect_now`, else on the next call; RTU: wait, flush).
  Status discard_late_replies(int err, bool reconnect_now);
  /// Runs one Modbus request on `a`'s drive with retries; maps the outcome to a Status.
  template <typename Op>
  Status request(Axis a, const char* what, Op&& op);
  Result<Readback> read_back(Axis a);
  Status write_command(Axis a, uint16_t command);
  Status write_move(Axis a, int32_t target_counts);
  Status stop_locked();
  Status fault_error(Axis a, const Readback& r) const;
  /// "pan drive (unit 1, at 12.5 deg, status 0x000a)": what an error says about the drive it concerns.
  std::string where(Axis a, const Readback& r) const;
  /// Stops both drives (best effort, logged) and returns `failure`: every failure while a drive may be moving ends
  /// here, so no axis finishes a move unattended.
  Status halt_after(Status failure);
  /// Polls both drives until `done` (Result<bool>(Axis, const Readback&); an error ends the wait) holds for both,
  /// a fault, a refused command, or the deadline; every failure stops both drives.
  template <typename Done>
  Status wait_both(const char* what, double timeout_s, Done&& done);

  ModbusStageConfig config_;
  std::mutex mutex_;  // one request at a time on the link; stop() may come from another thread
  /// modbus-tcp: takes the drive's lock file once, before the first connection (above, "Locks").
  Status lock_network_drive();

  modbus_t* ctx_ = nullptr;
  bool connected_ = false;
  std::optional<ProcessLock> tcp_drive_lock_;  // modbus-tcp: held from the first connect to the stage's end
  std::atomic<bool> stop_requested_{false};    // stop() during a move/home: the wait ends with kCancelled
};

}  // namespace vdrig::rig

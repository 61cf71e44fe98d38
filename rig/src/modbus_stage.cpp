#include "modbus_stage.hpp"

#include <modbus/modbus.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <thread>

#include "axis_settings.hpp"
#include "backends.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/rig/motion.hpp"

namespace vdrig::rig {
namespace mm = modbus_map;
namespace {

constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;

std::string hex16(unsigned v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%04x", v & 0xffffu);
  return buf;
}

ModbusAxisConfig parse_axis(Settings& parent, const nlohmann::json& section, const std::string& where) {
  Settings s(section, where, {"backend"});  // accepted in axis sections as before
  ModbusAxisConfig a;
  a.unit = static_cast<int>(s.required_integer("unit", 1, 247));  // 0 is broadcast, 248..255 reserved
  a.counts_per_degree = s.required_number("counts_per_degree", -1e9, 1e9);
  if (s.has("counts_per_degree") && std::abs(a.counts_per_degree) < 1e-9) s.fail("\"counts_per_degree\" must not be 0");
  a.axis = read_axis_spec(s);
  a.in_position_window_deg = s.number("in_position_window_deg", 0.05, 0.0, 10.0);
  s.reject_unknown({"unit", "counts_per_degree", "min_deg", "max_deg", "max_speed_deg_s", "accel_deg_s2", "continuous",
                    "in_position_window_deg"});
  // A 32-bit counter must hold the whole travel.
  const double max_counts =
      std::max(std::abs(a.axis.min_rad), std::abs(a.axis.max_rad)) * kDegPerRad * std::abs(a.counts_per_degree);
  if (!a.axis.continuous && max_counts > 2147483647.0) s.fail("travel exceeds the 32-bit encoder range");
  // The profile registers are uint32 counts/s and counts/s^2: a larger value would wrap silently on the wire.
  const double speed_counts = a.axis.max_speed_rad_s * kDegPerRad * std::abs(a.counts_per_degree);
  const double accel_counts = a.axis.accel_rad_s2 * kDegPerRad * std::abs(a.counts_per_degree);
  if (speed_counts > 4294967295.0)
    s.fail("max_speed_deg_s x |counts_per_degree| = " + std::to_string(speed_counts) +
           " counts/s exceeds the 32-bit profile velocity register");
  if (accel_counts > 4294967295.0)
    s.fail("accel_deg_s2 x |counts_per_degree| = " + std::to_string(accel_counts) +
           " counts/s^2 exceeds the 32-bit profile acceleration register");
  parent.absorb(s);
  return a;
}

bool is_link_error(int err) {
  switch (err) {
    case ECONNRESET:
    case EPIPE:
    case ECONNREFUSED:
    case ENOTCONN:
    case EBADF:
    case ECONNABORTED:
    case EHOSTUNREACH:
    case ENETUNREACH:
    case ENODEV:
    case ENXIO:
    case EIO:
      return true;
    default:
      return false;
  }
}

// Worth another attempt: a lost or garbled frame (noise on an RS-485 line, a late TCP answer that libmodbus
// rejects by transaction id), or a drive that says it is busy.
bool is_transient(int err) {
  return err == ETIMEDOUT || err == EMBBADCRC || err == EMBBADDATA || err == EMBBADEXC || err == EMBMDATA ||
         err == EMBBADSLAVE || err == EMBXSBUSY || err == EMBXGTAR || err == EINTR;
}

}  // namespace

Result<ModbusStageConfig> ModbusStageConfig::parse(const nlohmann::json& settings, bool rtu) {
  Settings s(settings, rtu ? "stage modbus-rtu" : "stage modbus-tcp", {"backend"});
  ModbusStageConfig c;
  c.rtu = rtu;
  if (rtu) {
    c.device = s.required_string("device");
    c.baud = static_cast<int>(s.integer("baud", 115200, 300, 4000000));
    c.parity = s.string("parity", "N", {"N", "E", "O"})[0];
    c.data_bits = static_cast<int>(s.integer("data_bits", 8, 5, 8));
    c.stop_bits = static_cast<int>(s.integer("stop_bits", 1, 1, 2));
  } else {
    c.host = s.required_string("host");
    c.port = static_cast<int>(s.integer("port", 502, 1, 65535));
  }
  c.response_timeout_s = s.number("response_timeout_s", 0.2, 0.001, 60.0);
  c.retries = static_cast<int>(s.integer("retries", 2, 0, 10));
  c.poll_interval_s = s.number("poll_interval_s", 0.02, 0.0, 5.0);
  c.move_timeout_s = s.number("move_timeout_s", 5.0, 0.01, 3600.0);
  c.home_timeout_s = s.number("home_timeout_s", 120.0, 0.01, 3600.0);
  c.word_order = s.string("word_order", "high-first", {"high-first", "low-first"}) == "low-first"
                     ? mm::WordOrder::kLowFirst
                     : mm::WordOrder::kHighFirst;
  c.register_base = static_cast<int>(s.integer("register_base", 0, 0, 65535 - mm::kRegisterCount));
  c.pan = parse_axis(s, s.object("pan", true), "pan");
  c.tilt = parse_axis(s, s.object("tilt", true), "tilt");
  if (s.has("pan") && s.has("tilt") && c.pan.unit == c.tilt.unit)
    s.fail("pan and tilt must have different \"unit\" ids");
  if (rtu)
    s.reject_unknown({"device", "baud", "parity", "data_bits", "stop_bits", "response_timeout_s", "retries",
                      "poll_interval_s", "move_timeout_s", "home_timeout_s", "word_order", "register_base", "pan",
                      "tilt"});
  else
    s.reject_unknown({"host", "port", "response_timeout_s", "retries", "poll_interval_s", "move_timeout_s",
                      "home_timeout_s", "word_order", "register_base", "pan", "tilt"});
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

ModbusStage::ModbusStage(ModbusStageConfig config) : config_(std::move(config)) {}

ModbusStage::~ModbusStage() {
  if (ctx_) {
    if (connected_) modbus_close(ctx_);
    modbus_free(ctx_);
  }
}

Status ModbusStage::connect() {
  std::lock_guard lock(mutex_);
  return ensure_connected();
}

Status ModbusStage::ensure_connected() {
  if (connected_) return Status::ok();
  if (!ctx_) {
    ctx_ = config_.rtu ? modbus_new_rtu(config_.device.c_str(), config_.baud, config_.parity, config_.data_bits,
                                        config_.stop_bits)
                       : modbus_new_tcp(config_.host.c_str(), config_.port);
    if (!ctx_)
      return make_error(ErrorCode::kInvalidArgument,
                        backend() + ": cannot create the Modbus context: " + modbus_strerror(errno));
    const double t = config_.response_timeout_s;
    const auto sec = static_cast<uint32_t>(t);
    modbus_set_response_timeout(ctx_, sec, static_cast<uint32_t>((t - sec) * 1e6));
    // We do our own recovery (retries, reconnect on the next call) so the caller sees every failure as a Status;
    // libmodbus' built-in recovery would hide a lost link inside a long blocking call.
    modbus_set_error_recovery(ctx_, MODBUS_ERROR_RECOVERY_NONE);
  }
  const std::string where = config_.rtu ? config_.device : config_.host + ":" + std::to_string(config_.port);
  if (!config_.rtu) VDRIG_TRY(lock_network_drive());
  if (modbus_connect(ctx_) == -1) {
    const int err = errno;
    if (err == ETIMEDOUT)
      return make_error(ErrorCode::kTimeout, backend() + ": no answer from " + where + " while connecting");
    return make_error(ErrorCode::kDisconnected,
                      backend() + ": cannot connect to " + where + ": " + modbus_strerror(err));
  }
  // A serial port is locked on its node, which exists only once opened; a network drive before a connection is made.
  if (config_.rtu)
    if (Status locked = lock_open_file(modbus_get_socket(ctx_), backend() + " serial port " + config_.device);
        !locked) {
      modbus_close(ctx_);
      return locked;
    }
  connected_ = true;
  log::get("rig")->info("{}: connected to {}", backend(), where);
  return Status::ok();
}

Status ModbusStage::lock_network_drive() {
  if (tcp_drive_lock_) return Status::ok();
  auto lock = lock_device(backend() + " drive " + config_.host + ":" + std::to_string(config_.port));
  if (!lock) return lock.error();
  tcp_drive_lock_ = std::move(lock.value());
  return Status::ok();
}

void ModbusStage::drop_connection(const char* why) {
  if (!connected_) return;
  log::get("rig")->warn("{}: link lost ({}); will reconnect on the next call", backend(), why);
  modbus_close(ctx_);
  connected_ = false;
}

template <typename Op>
Status ModbusStage::request(Axis a, const char* what, Op&& op) {
  std::lock_guard lock(mutex_);
  VDRIG_TRY(ensure_connected());
  modbus_set_slave(ctx_, axis(a).unit);
  int err = 0;
  bool timed_out = false;
  for (int attempt = 0; attempt <= config_.retries; ++attempt) {
    errno = 0;
    if (op(ctx_) != -1) return Status::ok();
    err = errno;
    timed_out = timed_out || err == ETIMEDOUT;
    const std::string ctx_msg = backend() + ": " + what + " on " + name(a) + " drive (unit " +
                                std::to_string(axis(a).unit) + "): " + modbus_strerror(err);
    if (is_link_error(err)) {
      drop_connection(modbus_strerror(err));
      return make_error(ErrorCode::kDisconnected, ctx_msg);
    }
    if (!is_transient(err)) return make_error(ErrorCode::kDevice, ctx_msg);
    log::get("rig")->debug("{} (attempt {} of {})", ctx_msg, attempt + 1, config_.retries + 1);
    const bool last = attempt == config_.retries;
    VDRIG_TRY(discard_late_replies(err, !last));
    if (!last) modbus_set_slave(ctx_, axis(a).unit);
  }
  const std::string msg = backend() + ": " + what + " on " + name(a) + " drive (unit " + std::to_string(axis(a).unit) +
                          ") failed after " + std::to_string(config_.retries + 1) +
                          " attempts: " + modbus_strerror(err);
  // A drive that answered late, or not at all, is a timeout whatever the retries then read.
  return make_error(timed_out ? ErrorCode::kTimeout : ErrorCode::kDevice, msg);
}

Status ModbusStage::discard_late_replies(int err, bool reconnect_now) {
  if (!config_.rtu) {
    // The answer to the failed request may still arrive, and libmodbus would read it as the answer to the next
    // one ("Invalid data", or worse, a plausible value of the wrong register). A fresh connection cannot carry
    // it: the drive writes it to a socket nobody reads any more.
    modbus_close(ctx_);
    connected_ = false;
    return reconnect_now ? ensure_connected() : Status::ok();
  }
  // On a serial line the late answer arrives within about one more response time: wait for it, then drop it.
  if (err == ETIMEDOUT) std::this_thread::sleep_for(std::chrono::duration<double>(config_.response_timeout_s));
  modbus_flush(ctx_);
  return Status::ok();
}

Result<ModbusStage::Readback> ModbusStage::read_back(Axis a) {
  uint16_t regs[mm::kPollCount] = {};
  VDRIG_TRY(request(a, "reading status", [&](modbus_t* ctx) {
    return modbus_read_registers(ctx, config_.register_base + mm::kPollFirst, mm::kPollCount, regs);
  }));
  Readback r;
  r.command = regs[mm::kCommand - mm::kPollFirst];
  r.status = regs[mm::kStatus - mm::kPollFirst];
  r.actual_counts = mm::get_i32(&regs[mm::kActualPosition - mm::kPollFirst], config_.word_order);
  r.fault_code = regs[mm::kFaultCode - mm::kPollFirst];
  return r;
}

Status ModbusStage::write_command(Axis a, uint16_t command) {
  return request(a, "writing command", [&](modbus_t* ctx) {
    return modbus_write_register(ctx, config_.register_base + mm::kCommand, command);
  });
}

Status ModbusStage::write_move(Axis a, int32_t target_counts) {
  const ModbusAxisConfig& ax = axis(a);
  const double cpr = std::abs(ax.counts_per_degree) * kDegPerRad;
  uint16_t regs[mm::kWritableCount] = {};
  // Validation guarantees both fit in 32 bits (parse_axis).
  mm::put_u32(&regs[mm::kProfileVelocity],
              static_cast<uint32_t>(std::max(1.0, std::round(ax.axis.max_speed_rad_s * cpr))), config_.word_order);
  mm::put_u32(&regs[mm::kProfileAccel], static_cast<uint32_t>(std::max(1.0, std::round(ax.axis.accel_rad_s2 * cpr))),
              config_.word_order);
  mm::put_i32(&regs[mm::kTargetPosition], target_counts, config_.word_order);
  regs[mm::kCommand] = mm::kCmdMove;
  VDRIG_TRY(request(a, "writing move", [&](modbus_t* ctx) {
    return modbus_write_registers(ctx, config_.register_base, mm::kWritableCount, regs);
  }));
  // A drive that clamps or ignores the profile or target (a value beyond its own limits, registers it does not
  // store) would make the move's duration and end point differ from what we computed: read them back.
  uint16_t stored[mm::kCommand] = {};
  VDRIG_TRY(request(a, "reading back the move", [&](modbus_t* ctx) {
    return modbus_read_registers(ctx, config_.register_base, mm::kCommand, stored);
  }));
  for (int i = 0; i < mm::kCommand; ++i)
    if (stored[i] != regs[i])
      return make_error(ErrorCode::kDevice, backend() + ": " + name(a) + " drive (unit " + std::to_string(ax.unit) +
                                                ") stores register " + std::to_string(i) + " as " + hex16(stored[i]) +
                                                ", written " + hex16(regs[i]) +
                                                " (profile or target out of the drive's range?)");
  return Status::ok();
}

std::string ModbusStage::where(Axis a, const Readback& r) const {
  return std::string(name(a)) + " drive (unit " + std::to_string(axis(a).unit) + ", at " +
         std::to_string(r.actual_counts / axis(a).counts_per_degree) + " deg, status " + hex16(r.status) + ")";
}

Status ModbusStage::fault_error(Axis a, const Readback& r) const {
  return make_error(ErrorCode::kDevice, backend() + ": " + where(a, r) + " reports fault code " + hex16(r.fault_code));
}

Status ModbusStage::stop_locked() {
  // Both drives get the stop even when the first write fails: a moving axis must not be left running.
  Status pan = write_command(Axis::kPan, mm::kCmdStop);
  Status tilt = write_command(Axis::kTilt, mm::kCmdStop);
  return pan ? tilt : pan;
}

Status ModbusStage::halt_after(Status failure) {
  const Status halt = stop_locked();  // the other axis would otherwise finish its move unattended
  if (!halt)
    log::get("rig")->warn("{}: stopping both drives after a failure failed too: {}", backend(), halt.describe());
  return failure;
}

template <typename Done>
Status ModbusStage::wait_both(const char* what, double timeout_s, Done&& done) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto deadline = start + std::chrono::duration<double>(timeout_s);
  // Drives reset the command register within a control cycle or two; one that still holds our command after
  // this long has refused it (a fault it does not report, a command it does not know, a drive in local mode).
  const auto refuse_after = start + std::chrono::duration<double>(std::max(0.25, 5.0 * config_.poll_interval_s));
  Readback last[2];
  for (;;) {
    bool all_done = true;
    for (Axis a : {Axis::kPan, Axis::kTilt}) {
      auto r = read_back(a);
      if (!r) return halt_after(r.error());
      last[a == Axis::kPan ? 0 : 1] = *r;
      if (r->status & mm::kStatusFault) return halt_after(fault_error(a, *r));
      if (r->command != mm::kCmdNone && !(r->status & mm::kStatusMoving) && Clock::now() >= refuse_after)
        return halt_after(make_error(ErrorCode::kDevice, backend() + ": " + where(a, *r) + " refused " + what +
                                                             " (command register still " + hex16(r->command) +
                                                             ", fault code " + hex16(r->fault_code) + ")"));
      Result<bool> axis_done = done(a, *r);
      if (!axis_done) return halt_after(axis_done.error());
      all_done = all_done && axis_done.value();
    }
    if (all_done) return Status::ok();
    if (stop_requested_.load())
      return halt_after(make_error(ErrorCode::kCancelled, backend() + ": " + what + " stopped on request"));
    if (Clock::now() >= deadline)
      return halt_after(make_error(
          ErrorCode::kTimeout, backend() + ": " + what + " not finished within " + std::to_string(timeout_s) + " s; " +
                                   where(Axis::kPan, last[0]) + ", " + where(Axis::kTilt, last[1])));
    std::this_thread::sleep_for(std::chrono::duration<double>(config_.poll_interval_s));
  }
}

Status ModbusStage::home() {
  stop_requested_ = false;
  for (Axis a : {Axis::kPan, Axis::kTilt}) {
    auto r = read_back(a);
    if (!r) return r.error();
    if (r->status & mm::kStatusFault) {
      // Homing is the documented recovery: the fault is cleared (and logged), the reference run re-establishes
      // the position the fault may have lost.
      log::get("rig")->warn("{}: clearing fault {} on {} drive before homing", backend(), hex16(r->fault_code),
                            name(a));
      VDRIG_TRY(write_command(a, mm::kCmdClearFault));
    }
  }
  VDRIG_TRY(write_command(Axis::kPan, mm::kCmdHome));
  if (Status s = write_command(Axis::kTilt, mm::kCmdHome); !s) return halt_after(s);
  // Done = referenced, standing still and at zero. Checking the position too guards against drives that keep the
  // "homed" bit of a previous reference run for a cycle after the new command.
  return wait_both("homing", config_.home_timeout_s, [&](Axis a, const Readback& r) -> Result<bool> {
    const double window = std::max(1.0, axis(a).in_position_window_deg * std::abs(axis(a).counts_per_degree));
    return (r.status & mm::kStatusHomed) && !(r.status & mm::kStatusMoving) && std::abs(r.actual_counts) <= window;
  });
}

Status ModbusStage::move_to(const PanTilt& target) {
  stop_requested_ = false;
  const double target_rad[2] = {target.pan_rad, target.tilt_rad};
  int32_t target_counts[2] = {};
  int32_t start_counts[2] = {};
  double profile_time_s = 0.0;
  for (Axis a : {Axis::kPan, Axis::kTilt}) {
    const int i = a == Axis::kPan ? 0 : 1;
    const ModbusAxisConfig& ax = axis(a);
    const double t = target_rad[i];
    if (!std::isfinite(t)) return make_error(ErrorCode::kInvalidArgument, backend() + ": non-finite target");
    auto r = read_back(a);
    if (!r) return r.error();
    if (r->status & mm::kStatusFault) return fault_error(a, *r);
    if (!(r->status & mm::kStatusHomed))
      return make_error(ErrorCode::kDevice, backend() + ": " + name(a) + " drive is not homed; call home() first");
    const double cpr = ax.counts_per_degree * kDegPerRad;
    double counts;
    if (ax.axis.continuous) {
      // Take the shorter way round from where the axis is; the counter keeps counting whole turns.
      const double current = r->actual_counts / cpr;
      counts = r->actual_counts + std::remainder(t - current, 2.0 * 3.14159265358979323846) * cpr;
    } else {
      if (t < ax.axis.min_rad - 1e-9 || t > ax.axis.max_rad + 1e-9)
        return make_error(ErrorCode::kInvalidArgument, backend() + ": " + name(a) + " target " +
                                                           std::to_string(t * kDegPerRad) + " deg outside [" +
                                                           std::to_string(ax.axis.min_rad * kDegPerRad) + ", " +
                                                           std::to_string(ax.axis.max_rad * kDegPerRad) + "] deg");
      counts = t * cpr;
    }
    if (std::abs(counts) > 2147483647.0)
      return make_error(ErrorCode::kInvalidArgument, backend() + ": target exceeds the 32-bit encoder range");
    target_counts[i] = static_cast<int32_t>(std::lround(counts));
    start_counts[i] = r->actual_counts;
    profile_time_s = std::max(profile_time_s, axis_move_time_s((counts - r->actual_counts) / cpr, ax.axis));
  }
  // Any failure from the first write on stops both drives: one of them may already be moving.
  if (Status s = write_move(Axis::kPan, target_counts[0]); !s) return halt_after(s);
  if (Status s = write_move(Axis::kTilt, target_counts[1]); !s) return halt_after(s);
  // A stuck axis is seen after twice the profile's time plus the margin, not after a fixed worst case.
  const double timeout_s = 2.0 * profile_time_s + config_.move_timeout_s;
  // Done = in position, not moving and within the window of OUR target: some drives leave "in position" set from
  // the previous move until their next control cycle, which alone would end the wait before the move started.
  return wait_both("move", timeout_s, [&](Axis a, const Readback& r) -> Result<bool> {
    const int i = a == Axis::kPan ? 0 : 1;
    const double window = std::max(1.0, axis(a).in_position_window_deg * std::abs(axis(a).counts_per_degree));
    // A drive travels between where it was and where it was sent (overshoot aside). A reading far outside that
    // span is a misread position, most often a word order that differs from the drive's: the target was then
    // written garbled too, and the drive is going somewhere else.
    const double lo = std::min(start_counts[i], target_counts[i]), hi = std::max(start_counts[i], target_counts[i]);
    const double slack = std::max(10.0 * window, 0.25 * (hi - lo));
    if (r.actual_counts < lo - slack || r.actual_counts > hi + slack)
      return make_error(ErrorCode::kDevice, backend() + ": " + where(a, r) +
                                                " reads a position outside its move from " +
                                                std::to_string(start_counts[i] / axis(a).counts_per_degree) + " to " +
                                                std::to_string(target_counts[i] / axis(a).counts_per_degree) +
                                                " deg: is \"word_order\" the drive's?");
    return (r.status & mm::kStatusInPosition) && !(r.status & mm::kStatusMoving) &&
           std::abs(static_cast<double>(r.actual_counts) - target_counts[i]) <= window;
  });
}

Result<PanTilt> ModbusStage::position() {
  auto pan = read_back(Axis::kPan);
  if (!pan) return pan.error();
  auto tilt = read_back(Axis::kTilt);
  if (!tilt) return tilt.error();
  PanTilt p;
  p.pan_rad = pan->actual_counts / (config_.pan.counts_per_degree * kDegPerRad);
  p.tilt_rad = tilt->actual_counts / (config_.tilt.counts_per_degree * kDegPerRad);
  return p;
}

Status ModbusStage::stop() {
  stop_requested_ = true;  // a move_to/home waiting on another thread ends instead of waiting for its timeout
  return stop_locked();
}

}  // namespace vdrig::rig

namespace vdrig::rig {

nlohmann::json ModbusStageConfig::effective() const {
  nlohmann::json j = {{"backend", rtu ? "modbus-rtu" : "modbus-tcp"},
                      {"response_timeout_s", response_timeout_s},
                      {"retries", retries},
                      {"poll_interval_s", poll_interval_s},
                      {"move_timeout_s", move_timeout_s},
                      {"home_timeout_s", home_timeout_s},
                      {"word_order", word_order == mm::WordOrder::kLowFirst ? "low-first" : "high-first"},
                      {"register_base", register_base}};
  if (rtu) {
    j["device"] = device;
    j["baud"] = baud;
    j["parity"] = std::string(1, parity);
    j["data_bits"] = data_bits;
    j["stop_bits"] = stop_bits;
  } else {
    j["host"] = host;
    j["port"] = port;
  }
  for (const auto& [key, a] : {std::pair{"pan", &pan}, std::pair{"tilt", &tilt}}) {
    nlohmann::json axis = axis_spec_json(a->axis);
    axis["unit"] = a->unit;
    axis["counts_per_degree"] = a->counts_per_degree;
    axis["in_position_window_deg"] = a->in_position_window_deg;
    // What the drive's profile registers will hold (docs/rig-modbus.md).
    axis["profile_velocity_counts_s"] =
        std::round(a->axis.max_speed_rad_s * kDegPerRad * std::abs(a->counts_per_degree));
    axis["profile_accel_counts_s2"] = std::round(a->axis.accel_rad_s2 * kDegPerRad * std::abs(a->counts_per_degree));
    j[key] = axis;
  }
  // The holding registers each drive is expected to have (docs/rig-modbus.md).
  j["register_map"] = {{"profile_velocity", register_base + mm::kProfileVelocity},
                       {"profile_accel", register_base + mm::kProfileAccel},
                       {"target_position", register_base + mm::kTargetPosition},
                       {"command", register_base + mm::kCommand},
                       {"status", register_base + mm::kStatus},
                       {"actual_position", register_base + mm::kActualPosition},
                       {"fault_code", register_base + mm::kFaultCode}};
  return j;
}

void register_modbus_backends(BackendRegistry& registry) {
  for (const bool rtu : {false, true}) {
    const auto parse = [rtu](const nlohmann::json& settings) { return ModbusStageConfig::parse(settings, rtu); };
    registry.add_stage(rtu ? "modbus-rtu" : "modbus-tcp",
                       [parse](const nlohmann::json& settings, RigContext&) -> Result<std::unique_ptr<PanTiltStage>> {
                         auto config = parse(settings);
                         if (!config) return config.error();
                         auto stage = std::make_unique<ModbusStage>(std::move(config.value()));
                         VDRIG_TRY(stage->connect());
                         return std::unique_ptr<PanTiltStage>(std::move(stage));
                       },
                       {.check = settings_check(parse)});
  }
}

}  // namespace vdrig::rig

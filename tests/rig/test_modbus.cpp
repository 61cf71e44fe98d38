// The modbus-tcp stage against two simulated drives served by a real libmodbus TCP server on 127.0.0.1: every
// request crosses the actual protocol (framing, unit ids, word order, exceptions, timeouts, a closed socket).
#include <gtest/gtest.h>

#ifdef VDRIG_HAVE_MODBUS

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <thread>

#include "modbus_map.hpp"
#include "modbus_stage.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {
namespace {
namespace mm = modbus_map;
using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

/// One simulated position drive: the register map of modbus_map.hpp and a motion that takes time.
struct DriveSim {
  modbus_mapping_t* map = modbus_mapping_new(0, 0, mm::kRegisterCount, 0);
  double pos = 0.0, from = 0.0, to = 0.0;  // counts
  Clock::time_point t0;
  double duration_s = 0.0;
  bool moving = false, homing = false, homed = false, fault = false, in_position = true;
  uint16_t fault_code = 0;
  bool fault_on_next_move = false;  // injection: the next move command latches a fault instead of moving
  bool stall = false;               // injection: moves start but never arrive
  DriveSim() = default;
  DriveSim(const DriveSim&) = delete;
  ~DriveSim() { modbus_mapping_free(map); }
};

class FakeDriveServer {
 public:
  explicit FakeDriveServer(mm::WordOrder order, int port = 0) : order_(order) {
    drives_[1] = std::make_unique<DriveSim>();
    drives_[2] = std::make_unique<DriveSim>();
    // Our own listening socket on port 0 gives a free port without a race; libmodbus then serves the accepted
    // socket (modbus_set_socket).
    listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    const int one = 1;
    ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(listen_fd_, 4) != 0)
      throw std::runtime_error("cannot listen on 127.0.0.1");
    socklen_t len = sizeof addr;
    ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] { serve(); });
  }
  ~FakeDriveServer() { shutdown(); }

  int port() const { return port_; }
  void shutdown() {
    if (stop_.exchange(true)) return;
    thread_.join();
    ::close(listen_fd_);
  }
  /// Runs `f` on a drive with the server paused.
  template <typename F>
  void with_drive(int unit, F&& f) {
    std::lock_guard lock(mutex_);
    f(*drives_.at(unit));
  }
  void set_unresponsive(bool on) { unresponsive_ = on; }
  int requests() const { return requests_; }

 private:
  void serve() {
    while (!stop_) {
      pollfd pl{listen_fd_, POLLIN, 0};
      if (::poll(&pl, 1, 10) <= 0) continue;
      const int fd = ::accept(listen_fd_, nullptr, nullptr);
      if (fd < 0) continue;
      serve_client(fd);
      ::close(fd);
    }
  }

  void serve_client(int fd) {
    modbus_t* ctx = modbus_new_tcp("127.0.0.1", port_);  // only for framing; the socket is ours
    modbus_set_socket(ctx, fd);
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    const int header = modbus_get_header_length(ctx);
    while (!stop_) {
      pollfd pc{fd, POLLIN, 0};
      if (::poll(&pc, 1, 10) <= 0) continue;
      const int rc = modbus_receive(ctx, query);
      if (rc == -1) break;  // client closed
      if (rc == 0) continue;
      ++requests_;
      if (unresponsive_) continue;  // the drive swallows the request
      const int unit = query[header - 1];
      std::lock_guard lock(mutex_);
      const auto it = drives_.find(unit);
      if (it == drives_.end()) {
        modbus_reply_exception(ctx, query, MODBUS_EXCEPTION_GATEWAY_TARGET);
        continue;
      }
      DriveSim& d = *it->second;
      update(d);
      modbus_reply(ctx, query, rc, d.map);
      execute(d);
      update(d);
    }
    modbus_free(ctx);  // does not close: modbus_free leaves the socket to us
  }

  void execute(DriveSim& d) {
    uint16_t* r = d.map->tab_registers;
    const uint16_t cmd = r[mm::kCommand];
    if (cmd == mm::kCmdNone) return;
    r[mm::kCommand] = mm::kCmdNone;  // accepted
    const auto start = [&](double target) {
      const double speed = std::max<uint32_t>(1, mm::get_u32(&r[mm::kProfileVelocity], order_));
      d.from = d.pos;
      d.to = target;
      d.t0 = Clock::now();
      d.duration_s = std::max(0.02, std::abs(target - d.pos) / speed);
      d.moving = true;
      d.in_position = false;
    };
    switch (cmd) {
      case mm::kCmdMove:
        if (d.fault) break;  // a faulted drive ignores motion commands
        if (d.fault_on_next_move) {
          d.fault_on_next_move = false;
          d.fault = true;
          d.fault_code = 0x2310;  // "continuous over-current" (CiA 402 style)
          break;
        }
        if (!d.homed) break;
        start(mm::get_i32(&r[mm::kTargetPosition], order_));
        break;
      case mm::kCmdHome:
        if (d.fault) break;
        d.homed = false;
        d.homing = true;
        d.moving = true;
        d.in_position = false;
        d.from = d.pos;
        d.t0 = Clock::now();
        d.duration_s = 0.03;
        break;
      case mm::kCmdStop:
        d.moving = d.homing = false;
        d.in_position = true;
        break;
      case mm::kCmdClearFault:
        d.fault = false;
        d.fault_code = 0;
        break;
      default:
        break;
    }
  }

  void update(DriveSim& d) {
    if (d.moving) {
      const double f = std::chrono::duration<double>(Clock::now() - d.t0).count() / d.duration_s;
      if (d.homing) {
        if (f >= 1.0) {  // reference found: the position becomes 0
          d.pos = 0.0;
          d.moving = d.homing = false;
          d.homed = d.in_position = true;
        }
      } else if (d.stall) {
        d.pos = d.from + 0.1 * (d.to - d.from);  // stuck after a few counts
      } else if (f >= 1.0) {
        d.pos = d.to;
        d.moving = false;
        d.in_position = true;
      } else {
        d.pos = d.from + f * (d.to - d.from);
      }
    }
    uint16_t* r = d.map->tab_registers;
    r[mm::kStatus] =
        static_cast<uint16_t>((d.in_position ? mm::kStatusInPosition : 0) | (d.homed ? mm::kStatusHomed : 0) |
                              (d.fault ? mm::kStatusFault : 0) | (d.moving ? mm::kStatusMoving : 0));
    mm::put_i32(&r[mm::kActualPosition], static_cast<int32_t>(std::lround(d.pos)), order_);
    r[mm::kFaultCode] = d.fault_code;
  }

  mm::WordOrder order_;
  int listen_fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<bool> unresponsive_{false};
  std::atomic<int> requests_{0};
  std::mutex mutex_;
  std::map<int, std::unique_ptr<DriveSim>> drives_;
  std::thread thread_;
};

nlohmann::json stage_config(int port, const char* word_order = "high-first") {
  // 1000 counts/deg: a 120 deg move is 120000 counts, beyond 16 bits, so both words of every 32-bit value matter.
  return {{"backend", "modbus-tcp"},
          {"host", "127.0.0.1"},
          {"port", port},
          {"word_order", word_order},
          {"response_timeout_s", 0.1},
          {"retries", 1},
          {"poll_interval_s", 0.005},
          {"move_timeout_s", 0.4},
          {"home_timeout_s", 1.0},
          // A fast profile: a move may take twice its profile time plus move_timeout_s (the fake drives move in
          // milliseconds whatever they are told).
          {"pan",
           {{"unit", 1},
            {"counts_per_degree", 1000},
            {"min_deg", -180},
            {"max_deg", 180},
            {"max_speed_deg_s", 2000},
            {"accel_deg_s2", 20000}}},
          {"tilt",
           {{"unit", 2},
            {"counts_per_degree", -500},
            {"min_deg", -90},
            {"max_deg", 90},
            {"max_speed_deg_s", 2000},
            {"accel_deg_s2", 20000}}}};
}

std::unique_ptr<ModbusStage> make_stage(const nlohmann::json& config) {
  auto c = ModbusStageConfig::parse(config, false);
  if (!c) ADD_FAILURE() << c.error().describe();
  return std::make_unique<ModbusStage>(c.value());
}

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

class ModbusStageTest : public ::testing::TestWithParam<const char*> {};

TEST_P(ModbusStageTest, HomesMovesAndReadsBackInBothWordOrders) {
  const std::string order = GetParam();
  FakeDriveServer server(order == "low-first" ? mm::WordOrder::kLowFirst : mm::WordOrder::kHighFirst);
  auto stage = make_stage(stage_config(server.port(), GetParam()));

  // Not homed yet: a move is refused by us, not sent to the drive.
  const Status early = stage->move_to({0.1, 0.1});
  ASSERT_FALSE(early);
  EXPECT_EQ(early.error().code, ErrorCode::kDevice);
  EXPECT_NE(early.error().message.find("not homed"), std::string::npos) << early.describe();

  server.with_drive(1, [](DriveSim& d) { d.pos = 4321; });
  ASSERT_TRUE(stage->home()) << "home";
  auto p0 = stage->position();
  ASSERT_TRUE(p0) << p0.error().describe();
  EXPECT_EQ(p0->pan_rad, 0.0);
  EXPECT_EQ(p0->tilt_rad, 0.0);

  const auto t0 = Clock::now();
  const Status moved = stage->move_to({-120.0 * kDeg, 37.5 * kDeg});
  ASSERT_TRUE(moved) << moved.describe();
  // The simulated pan motion takes 120000 counts / 2e6 counts/s = 60 ms: move_to must have waited for it.
  EXPECT_GE(seconds_since(t0), 0.05);

  // What the drives were told, in counts (tilt has negative counts_per_degree: -500 * 37.5 = -18750).
  server.with_drive(1, [](DriveSim& d) { EXPECT_EQ(std::lround(d.pos), -120000); });
  server.with_drive(2, [](DriveSim& d) { EXPECT_EQ(std::lround(d.pos), -18750); });
  auto p = stage->position();
  ASSERT_TRUE(p) << p.error().describe();
  EXPECT_NEAR(p->pan_rad / kDeg, -120.0, 1e-9);
  EXPECT_NEAR(p->tilt_rad / kDeg, 37.5, 1e-9);

  // Out of the axis limits: rejected before anything is sent.
  const Status far = stage->move_to({0.0, 100.0 * kDeg});
  ASSERT_FALSE(far);
  EXPECT_EQ(far.error().code, ErrorCode::kInvalidArgument);
}

INSTANTIATE_TEST_SUITE_P(WordOrder, ModbusStageTest, ::testing::Values("high-first", "low-first"));

TEST(ModbusStage, MismatchedWordOrderReadsAWrongPosition) {
  // The reason word_order is a setting: the same registers read with the other order give another number.
  FakeDriveServer server(mm::WordOrder::kLowFirst);
  server.with_drive(1, [](DriveSim& d) { d.pos = -120000; });
  server.with_drive(2, [](DriveSim& d) { d.pos = 0; });
  auto stage = make_stage(stage_config(server.port(), "high-first"));
  auto p = stage->position();
  ASSERT_TRUE(p) << p.error().describe();
  EXPECT_GT(std::abs(p->pan_rad / kDeg + 120.0), 1.0);
}

TEST(ModbusStage, DriveFaultIsDeviceErrorWithCodeAndHomeRecovers) {
  FakeDriveServer server(mm::WordOrder::kHighFirst);
  auto stage = make_stage(stage_config(server.port()));
  ASSERT_TRUE(stage->home());
  server.with_drive(2, [](DriveSim& d) { d.fault_on_next_move = true; });
  const Status s = stage->move_to({10.0 * kDeg, 10.0 * kDeg});
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_NE(s.error().message.find("tilt"), std::string::npos) << s.describe();
  EXPECT_NE(s.error().message.find("0x2310"), std::string::npos) << s.describe();
  // While latched, every further move is refused with the same code.
  const Status again = stage->move_to({0.0, 0.0});
  ASSERT_FALSE(again);
  EXPECT_EQ(again.error().code, ErrorCode::kDevice);
  // home() clears the fault and references again.
  ASSERT_TRUE(stage->home());
  EXPECT_TRUE(stage->move_to({5.0 * kDeg, -5.0 * kDeg}));
}

TEST(ModbusStage, StalledMoveTimesOutAndStopsTheDrives) {
  FakeDriveServer server(mm::WordOrder::kHighFirst);
  auto stage = make_stage(stage_config(server.port()));
  ASSERT_TRUE(stage->home());
  server.with_drive(1, [](DriveSim& d) { d.stall = true; });
  const auto t0 = Clock::now();
  const Status s = stage->move_to({90.0 * kDeg, 0.0});
  const double took = seconds_since(t0);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kTimeout) << s.describe();
  EXPECT_GE(took, 0.4);  // move_timeout_s
  EXPECT_LT(took, 2.0);
  server.with_drive(1, [](DriveSim& d) { EXPECT_FALSE(d.moving) << "the stage must stop a timed-out move"; });
}

TEST(ModbusStage, UnresponsiveDriveTimesOutAfterRetries) {
  FakeDriveServer server(mm::WordOrder::kHighFirst);
  auto stage = make_stage(stage_config(server.port()));
  ASSERT_TRUE(stage->position());
  const int before = server.requests();
  server.set_unresponsive(true);
  const auto t0 = Clock::now();
  auto p = stage->position();
  const double took = seconds_since(t0);
  ASSERT_FALSE(p);
  EXPECT_EQ(p.error().code, ErrorCode::kTimeout) << p.error().describe();
  EXPECT_EQ(server.requests() - before, 2);  // one attempt + retries = 1
  EXPECT_GE(took, 0.19);                     // 2 x response_timeout_s
  EXPECT_LT(took, 1.0);
  // The drive answers again: the next call works (on a fresh connection).
  server.set_unresponsive(false);
  EXPECT_TRUE(stage->position());
}

TEST(ModbusStage, ServerGoneIsDisconnectedAndReconnectsOnNextCall) {
  auto server = std::make_unique<FakeDriveServer>(mm::WordOrder::kHighFirst);
  const int port = server->port();
  auto stage = make_stage(stage_config(port));
  ASSERT_TRUE(stage->home());
  ASSERT_TRUE(stage->move_to({30.0 * kDeg, 0.0}));
  server.reset();  // closes the connection and the listener

  auto p = stage->position();
  ASSERT_FALSE(p);
  EXPECT_EQ(p.error().code, ErrorCode::kDisconnected) << p.error().describe();
  const Status s = stage->move_to({0.0, 0.0});  // reconnect attempt: refused
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDisconnected) << s.describe();

  server = std::make_unique<FakeDriveServer>(mm::WordOrder::kHighFirst, port);  // drives back (power-cycled)
  server->with_drive(1, [](DriveSim& d) { d.pos = 2000; });
  auto back = stage->position();
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_NEAR(back->pan_rad / kDeg, 2.0, 1e-9);
}

TEST(ModbusStage, RegistryBuildsTheStageByName) {
  FakeDriveServer server(mm::WordOrder::kHighFirst);
  BackendRegistry registry;
  register_hardware_backends(registry);
  const auto names = registry.stage_backends();
  EXPECT_NE(std::find(names.begin(), names.end(), "modbus-tcp"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "modbus-rtu"), names.end());
  // A camera that never captures, so make_rig has one.
  registry.add_camera("none",
                      [](const nlohmann::json&, RigContext&) -> Result<std::unique_ptr<Camera>> {
                        return make_error(ErrorCode::kUnsupported, "test camera");
                      },
                      {.check = [](const nlohmann::json& section) -> Result<nlohmann::json> { return section; }});
  nlohmann::json config = {{"stage", stage_config(server.port())}, {"camera", {{"backend", "none"}}}};
  auto rig = registry.make_rig(config);
  ASSERT_FALSE(rig);
  EXPECT_EQ(rig.error().code, ErrorCode::kUnsupported) << "the stage was built, then the camera failed";

  // With nothing listening, the factory fails early with kDisconnected.
  config["stage"]["port"] = 1;
  rig = registry.make_rig(config);
  ASSERT_FALSE(rig);
  EXPECT_EQ(rig.error().code, ErrorCode::kDisconnected) << rig.error().describe();
}

TEST(ModbusStage, BadConfigIsRejectedWithReasons) {
  const auto reason = [](nlohmann::json c, bool rtu = false) {
    auto r = ModbusStageConfig::parse(c, rtu);
    EXPECT_FALSE(r) << c.dump();
    if (r) return std::string();
    EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
    return r.error().message;
  };
  auto good = stage_config(5020);
  ASSERT_TRUE(ModbusStageConfig::parse(good, false));

  auto c = good;
  c.erase("host");
  EXPECT_NE(reason(c).find("\"host\" is required"), std::string::npos);
  c = good;
  c["pan"]["counts_per_degree"] = 0;
  EXPECT_NE(reason(c).find("pan: \"counts_per_degree\" must not be 0"), std::string::npos);
  c = good;
  c["tilt"]["min_deg"] = 95;
  EXPECT_NE(reason(c).find("tilt: \"min_deg\" must be below \"max_deg\""), std::string::npos);
  c = good;
  c["tilt"]["unit"] = 1;
  EXPECT_NE(reason(c).find("different \"unit\""), std::string::npos);
  c = good;
  c["pan"]["unit"] = 0;
  EXPECT_NE(reason(c).find("\"unit\" = 0 is outside [1, 247]"), std::string::npos);
  c = good;
  c["word_order"] = "middle-endian";
  EXPECT_NE(reason(c).find("word_order"), std::string::npos);
  c = good;
  c["port"] = 70000;
  EXPECT_NE(reason(c).find("\"port\""), std::string::npos);
  c = good;
  c["move_timeout"] = 3;  // typo of move_timeout_s
  EXPECT_NE(reason(c).find("unknown setting \"move_timeout\""), std::string::npos);
  c = good;
  c.erase("tilt");
  EXPECT_NE(reason(c).find("\"tilt\" (an object) is required"), std::string::npos);
  c = good;
  c["pan"]["max_speed_deg_s"] = "fast";
  EXPECT_NE(reason(c).find("must be a number"), std::string::npos);
  // RTU needs a device and a known parity; all problems are reported at once.
  c = good;
  c.erase("host");
  c.erase("port");
  c["parity"] = "X";
  const std::string rtu = reason(c, true);
  EXPECT_NE(rtu.find("\"device\" is required"), std::string::npos) << rtu;
  EXPECT_NE(rtu.find("\"parity\""), std::string::npos) << rtu;
}

}  // namespace
}  // namespace vdrig::rig

#else

TEST(ModbusStage, NotBuilt) { GTEST_SKIP() << "built without libmodbus (VDRIG_WITH_MODBUS=OFF)"; }

#endif

// The modbus-tcp stage against an independent peer: two drives emulated from docs/rig-modbus.md alone by
// tests/rig/modbus_drive_peer.py on Debian's python3-pymodbus, in a process of their own, with the faults driven from
// the peer's side (alarm, stuck axis, exception answers, late answers, server gone, server restarted).
#include <gtest/gtest.h>

#ifdef VDRIG_HAVE_MODBUS

#include <chrono>
#include <cmath>

#include "modbus_stage.hpp"
#include "vdrig/test/modbus_peer.hpp"

namespace vdrig::rig {
namespace {
using Clock = std::chrono::steady_clock;
using test::ModbusPeer;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// 1000 counts/deg (a 70 deg move is beyond 16 bits), 90 deg/s, 900 deg/s^2: a 10 deg move takes 0.21 s.
nlohmann::json peer_stage_config(int port, const char* word_order = "high-first") {
  auto axis = [](int unit, double cpd, double lo, double hi) {
    return nlohmann::json{{"unit", unit},
                          {"counts_per_degree", cpd},
                          {"min_deg", lo},
                          {"max_deg", hi},
                          {"max_speed_deg_s", 90},
                          {"accel_deg_s2", 900},
                          {"in_position_window_deg", 0.01}};
  };
  return {{"backend", "modbus-tcp"},
          {"host", "127.0.0.1"},
          {"port", port},
          {"word_order", word_order},
          {"response_timeout_s", 0.1},
          {"retries", 1},
          {"poll_interval_s", 0.01},
          {"move_timeout_s", 0.3},
          {"home_timeout_s", 2.0},
          {"pan", axis(1, 1000, -180, 180)},
          {"tilt", axis(2, -1000, -90, 90)}};
}

std::unique_ptr<ModbusStage> make_stage(const nlohmann::json& config) {
  auto c = ModbusStageConfig::parse(config, false);
  if (!c) {
    ADD_FAILURE() << c.error().describe();
    return nullptr;
  }
  return std::make_unique<ModbusStage>(c.value());
}

class PeerTest : public ::testing::Test {
 protected:
  void start(const std::string& peer_args = "", const char* word_order = "high-first") {
    if (const std::string why = test::modbus_peer_unavailable(); !why.empty()) GTEST_SKIP() << why;
    peer_ = std::make_unique<ModbusPeer>(peer_args);
    ASSERT_GT(peer_->port(), 0) << "the pymodbus peer did not start";
    stage_ = make_stage(peer_stage_config(peer_->port(), word_order));
    ASSERT_TRUE(stage_);
    const Status homed = stage_->home();
    ASSERT_TRUE(homed) << homed.describe();
  }
  void expect_both_standing() {
    EXPECT_FALSE(peer_->moving(1)) << peer_->query(1);
    EXPECT_FALSE(peer_->moving(2)) << peer_->query(2);
  }
  std::unique_ptr<ModbusPeer> peer_;
  std::unique_ptr<ModbusStage> stage_;
};

TEST_F(PeerTest, MovesAndReadsBackInBothWordOrders) {
  for (const char* order : {"high-first", "low-first"}) {
    SCOPED_TRACE(order);
    start(std::string("--word-order ") + order, order);
    if (IsSkipped()) return;
    const Status moved = stage_->move_to({70.0 * kDeg, -12.5 * kDeg});
    ASSERT_TRUE(moved) << moved.describe();
    auto p = stage_->position();
    ASSERT_TRUE(p) << p.error().describe();
    EXPECT_NEAR(p->pan_rad / kDeg, 70.0, 0.01);
    EXPECT_NEAR(p->tilt_rad / kDeg, -12.5, 0.01);
    // What the drives were sent, in their own counts (tilt counts_per_degree is -1000).
    EXPECT_NE(peer_->query(1).find("target=70000 "), std::string::npos) << peer_->query(1);
    EXPECT_NE(peer_->query(2).find("target=12500 "), std::string::npos) << peer_->query(2);
  }
}

TEST_F(PeerTest, WordOrderMismatchIsCaughtDuringTheMove) {
  // The drive takes high-first, vdrig is told low-first: every 32-bit value is garbled both ways, so the position
  // at rest reads right; the readings during the move cannot.
  start("--word-order high-first", "low-first");
  if (IsSkipped()) return;
  const Status s = stage_->move_to({5.0 * kDeg, 0.0});
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_NE(s.error().message.find("word_order"), std::string::npos) << s.describe();
  expect_both_standing();
}

TEST_F(PeerTest, AlarmDuringAMoveStopsBothAxes) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(peer_->command("on_move 0.05 alarm 2 8976"));
  const auto t0 = Clock::now();
  const Status s = stage_->move_to({40.0 * kDeg, 40.0 * kDeg});  // 0.54 s each: both are moving at 0.05 s
  ASSERT_FALSE(s);
  EXPECT_LT(seconds_since(t0), 0.5);  // well before the 0.54 s the moves take
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_NE(s.error().message.find("tilt drive (unit 2, at "), std::string::npos) << s.describe();
  EXPECT_NE(s.error().message.find("0x2310"), std::string::npos) << s.describe();
  expect_both_standing();
  // Homing clears the alarm and references again; then the stage moves.
  ASSERT_TRUE(stage_->home());
  EXPECT_TRUE(stage_->move_to({1.0 * kDeg, 1.0 * kDeg}));
}

TEST_F(PeerTest, StuckAxisTimesOutSoonAfterItsProfileTimeAndStopsBothAxes) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(peer_->command("on_move 0 stuck 1"));
  const auto t0 = Clock::now();
  const Status s = stage_->move_to({10.0 * kDeg, 10.0 * kDeg});  // profile 0.21 s: 2 x 0.21 + 0.3 s allowed
  const double took = seconds_since(t0);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kTimeout) << s.describe();
  EXPECT_GE(took, 0.7);
  EXPECT_LT(took, 1.5);
  EXPECT_NE(s.error().message.find("pan drive (unit 1, at 0.0"), std::string::npos) << s.describe();
  expect_both_standing();
}

TEST_F(PeerTest, ExceptionAnswersAreDeviceErrorsAndAMoveStopsBothAxes) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(peer_->command("exception 1 4 100"));  // slave device failure
  auto p = stage_->position();
  ASSERT_FALSE(p);
  EXPECT_EQ(p.error().code, ErrorCode::kDevice);
  EXPECT_NE(p.error().message.find("pan drive (unit 1)"), std::string::npos) << p.error().describe();
  ASSERT_TRUE(peer_->command("clear"));
  ASSERT_TRUE(stage_->position());

  ASSERT_TRUE(peer_->command("on_move 0.05 exception 2 4 1000"));
  const Status s = stage_->move_to({40.0 * kDeg, 40.0 * kDeg});
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_NE(s.error().message.find("tilt"), std::string::npos) << s.describe();
  EXPECT_FALSE(peer_->moving(1)) << "pan must not finish its move unattended: " << peer_->query(1);
  ASSERT_TRUE(peer_->command("clear"));
}

TEST_F(PeerTest, ALateAnswerIsDiscardedTheErrorIsATimeoutAndTheNextCommandWorks) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(stage_->move_to({3.0 * kDeg, 4.0 * kDeg}));
  // One late answer: the retry (on a fresh connection) gets the right one.
  ASSERT_TRUE(peer_->command("delay 1 0.25 1"));
  auto once = stage_->position();
  ASSERT_TRUE(once) << once.error().describe();
  EXPECT_NEAR(once->pan_rad / kDeg, 3.0, 0.01);
  // Late every time: a timeout, not "Invalid data" from reading an earlier answer.
  ASSERT_TRUE(peer_->command("delay 1 0.25 2"));
  auto late = stage_->position();
  ASSERT_FALSE(late);
  EXPECT_EQ(late.error().code, ErrorCode::kTimeout) << late.error().describe();
  // The late answers arrive while the next commands run: they must not be taken for theirs.
  const Status moved = stage_->move_to({-6.0 * kDeg, 2.0 * kDeg});
  ASSERT_TRUE(moved) << moved.describe();
  auto p = stage_->position();
  ASSERT_TRUE(p) << p.error().describe();
  EXPECT_NEAR(p->pan_rad / kDeg, -6.0, 0.01);
  EXPECT_NEAR(p->tilt_rad / kDeg, 2.0, 0.01);
}

TEST_F(PeerTest, ServerStoppingMidMoveIsDisconnectedWithoutHanging) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(peer_->command("on_move 0.05 stop_server"));
  const auto t0 = Clock::now();
  const Status s = stage_->move_to({40.0 * kDeg, 40.0 * kDeg});
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDisconnected) << s.describe();
  EXPECT_LT(seconds_since(t0), 1.0);
  auto p = stage_->position();
  ASSERT_FALSE(p);
  EXPECT_EQ(p.error().code, ErrorCode::kDisconnected) << p.error().describe();
}

TEST_F(PeerTest, ServerRestartingMidSessionReconnects) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(peer_->command("on_move 0.05 restart_server 0.2"));
  const Status s = stage_->move_to({40.0 * kDeg, 40.0 * kDeg});
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDisconnected) << s.describe();
  ASSERT_TRUE(peer_->expect("LISTENING", 5.0));
  const Status again = stage_->move_to({40.0 * kDeg, 40.0 * kDeg});
  ASSERT_TRUE(again) << again.describe();
  auto p = stage_->position();
  ASSERT_TRUE(p) << p.error().describe();
  EXPECT_NEAR(p->pan_rad / kDeg, 40.0, 0.01);
}

TEST_F(PeerTest, ARefusedCommandIsSeenInTheCommandRegister) {
  start();
  if (IsSkipped()) return;
  ASSERT_TRUE(peer_->command("refuse 2"));
  const auto t0 = Clock::now();
  const Status s = stage_->move_to({10.0 * kDeg, 10.0 * kDeg});
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDevice) << s.describe();
  EXPECT_NE(s.error().message.find("tilt drive (unit 2"), std::string::npos) << s.describe();
  EXPECT_NE(s.error().message.find("refused move"), std::string::npos) << s.describe();
  EXPECT_LT(seconds_since(t0), 0.7);  // before the timeout would have said so
  expect_both_standing();
}

TEST(ModbusPeerConfig, ProfileRegistersThatWouldWrapAreRejected) {
  // 10000 deg/s x 1e6 counts/deg = 1e10 counts/s: wraps to 1410065408 in a uint32 register.
  auto config = peer_stage_config(502);
  config["pan"]["counts_per_degree"] = 1e6;
  config["pan"]["max_speed_deg_s"] = 10000;
  config["pan"]["accel_deg_s2"] = 100000;
  auto c = ModbusStageConfig::parse(config, false);
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(c.error().message.find("32-bit profile velocity"), std::string::npos) << c.error().message;
  EXPECT_NE(c.error().message.find("32-bit profile acceleration"), std::string::npos) << c.error().message;
}

}  // namespace
}  // namespace vdrig::rig

#else
TEST(ModbusPeer, NotBuilt) { GTEST_SKIP() << "built without libmodbus (VDRIG_WITH_MODBUS=OFF)"; }
#endif

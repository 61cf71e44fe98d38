// vdrigd while the stage moves: `home` and `move` run beside the daemon's loop, so every client is answered while
// an axis travels (or is stuck), and `stop` halts the axes at once. The stage is the independent pymodbus drive peer
// (tests/rig/modbus_drive_peer.py) with slow axes; the camera is the simulator's.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "test_support.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/test/modbus_peer.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

TEST(VdrigdStage, AnswersWhileTheStageMovesAndStopHaltsIt) {
  if (const std::string why = test::modbus_peer_unavailable(); !why.empty()) GTEST_SKIP() << why;
  test::ModbusPeer peer;
  ASSERT_GT(peer.port(), 0);
  vdrig::test::TempDir root("vdrigd_stage");
  DaemonConfig config;
  config.runtime_dir = root.path() / "run";
  config.sessions_dir = root.path() / "sessions";
  // 10 deg/s: a 60 deg move takes over 6 s, far longer than any answer may wait.
  auto axis = [](int unit) {
    return json{{"unit", unit},  {"counts_per_degree", 1000}, {"min_deg", -90},
                {"max_deg", 90}, {"max_speed_deg_s", 10},     {"accel_deg_s2", 100}};
  };
  config.rig_config = testing::small_sim_config();
  config.rig_config.erase("light");
  config.rig_config["stage"] = {{"backend", "modbus-tcp"}, {"host", "127.0.0.1"}, {"port", peer.port()},
                                {"poll_interval_s", 0.01}, {"pan", axis(1)},      {"tilt", axis(2)}};
  config.make_rig = [](const json& rc) {
    rig::BackendRegistry registry;
    rig::register_hardware_backends(registry);
    sim::register_backends(registry);
    return registry.make_rig(rc);
  };
  config.capture.disk_reserve_bytes = 0;
  Daemon daemon(config);
  const Status started = daemon.start();
  ASSERT_TRUE(started) << started.describe();
  Status loop;
  std::thread thread([&] { loop = daemon.run(); });

  const int mover = testing::connect_unix(daemon.socket_path());
  const int watcher = testing::connect_unix(daemon.socket_path());
  ASSERT_GE(mover, 0);
  ASSERT_GE(watcher, 0);
  std::string mover_buf, watcher_buf;
  const json homed = testing::request(mover, mover_buf, {{"cmd", "home"}, {"id", 1}});
  ASSERT_EQ(homed.value("ok", false), true) << homed.dump();
  EXPECT_EQ(homed["id"], 1);

  ASSERT_TRUE(
      testing::send_all(mover, json{{"cmd", "move"}, {"id", 2}, {"pan_deg", 60}, {"tilt_deg", 0}}.dump() + "\n"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  auto t0 = Clock::now();
  const json status = testing::request(watcher, watcher_buf, {{"cmd", "status"}});
  EXPECT_LT(seconds_since(t0), 0.5) << "status waited for the move";
  EXPECT_EQ(status.value("stage", ""), "moving") << status.dump();
  const json again = testing::request(watcher, watcher_buf, {{"cmd", "move"}, {"pan_deg", 1}, {"tilt_deg", 1}});
  EXPECT_EQ(again.value("code", ""), "busy") << again.dump();
  EXPECT_TRUE(peer.moving(1));

  t0 = Clock::now();
  const json stopped = testing::request(watcher, watcher_buf, {{"cmd", "stop"}});
  EXPECT_EQ(stopped.value("ok", false), true) << stopped.dump();
  EXPECT_EQ(stopped.value("stopped", ""), "moving") << stopped.dump();
  // The move's own reply comes now, as cancelled, long before the 6 s the move would have taken.
  const json moved = testing::request(mover, mover_buf, {{"cmd", "status"}, {"id", 3}}, 3000);
  EXPECT_EQ(moved.value("id", 0), 2) << moved.dump();
  EXPECT_EQ(moved.value("code", ""), "cancelled") << moved.dump();
  EXPECT_LT(seconds_since(t0), 1.5);
  EXPECT_FALSE(peer.moving(1)) << peer.query(1);
  EXPECT_FALSE(peer.moving(2)) << peer.query(2);
  // The status sent behind the move is answered after it, in order.
  auto behind = testing::read_line(mover, mover_buf, 3000);
  ASSERT_TRUE(behind);
  EXPECT_EQ(json::parse(*behind).value("id", 0), 3) << *behind;

  const json small = testing::request(watcher, watcher_buf, {{"cmd", "move"}, {"pan_deg", 2}, {"tilt_deg", -1}});
  EXPECT_EQ(small.value("ok", false), true) << small.dump();
  EXPECT_NEAR(small.value("pan_deg", 0.0), 2.0, 0.01) << small.dump();

  ::close(mover);
  ::close(watcher);
  daemon.request_stop();
  thread.join();
  EXPECT_TRUE(loop) << loop.describe();
}

}  // namespace
}  // namespace vdrig::capture

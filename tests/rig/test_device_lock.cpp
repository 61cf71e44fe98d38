// One process drives a device, wherever each process's runtime folder is (issue 23: a second vdrigd with another
// --runtime-dir drove the same Modbus drive at once). A modbus-tcp stage holds a lock file named from the drive's
// host and port in a fixed folder; a modbus-rtu stage flocks its serial port's node (a pty stands in for it). A
// second stage on the same drive fails to connect, naming the holder's PID; the first one's end releases the drive.
#include <gtest/gtest.h>

#ifdef VDRIG_HAVE_MODBUS

#include <pty.h>
#include <unistd.h>

#include "modbus_stage.hpp"
#include "vdrig/test/modbus_peer.hpp"

namespace vdrig::rig {
namespace {

std::unique_ptr<ModbusStage> make_stage(const nlohmann::json& settings, bool rtu) {
  auto config = ModbusStageConfig::parse(settings, rtu);
  if (!config) {
    ADD_FAILURE() << config.error().describe();
    return nullptr;
  }
  return std::make_unique<ModbusStage>(config.value());
}

nlohmann::json axes(nlohmann::json settings) {
  settings["pan"] = {{"unit", 1}, {"counts_per_degree", 1000}};
  settings["tilt"] = {{"unit", 2}, {"counts_per_degree", 1000}};
  return settings;
}

std::string in_use_by_us() { return "is in use by PID " + std::to_string(::getpid()); }

TEST(DeviceLock, ASecondStageOnTheSameTcpDriveIsRefusedNamingTheHolder) {
  if (const std::string why = test::modbus_peer_unavailable(); !why.empty()) GTEST_SKIP() << why;
  test::ModbusPeer peer;
  ASSERT_GT(peer.port(), 0) << "the pymodbus peer did not start";
  const auto settings = axes({{"host", "127.0.0.1"}, {"port", peer.port()}});
  auto first = make_stage(settings, false);
  ASSERT_TRUE(first);
  const Status connected = first->connect();
  ASSERT_TRUE(connected) << connected.describe();

  auto second = make_stage(settings, false);
  ASSERT_TRUE(second);
  const Status refused = second->connect();
  ASSERT_FALSE(refused) << "two stages drive 127.0.0.1:" << peer.port() << " at once";
  EXPECT_STREQ(to_string(refused.error().code), "in use") << refused.describe();
  EXPECT_NE(refused.error().message.find("127.0.0.1:" + std::to_string(peer.port())), std::string::npos)
      << refused.describe();
  EXPECT_NE(refused.error().message.find(in_use_by_us()), std::string::npos) << refused.describe();
  // Nor does a later call of the refused stage reach the drive.
  EXPECT_FALSE(second->position());

  first.reset();  // the drive is free again
  const Status after = second->connect();
  EXPECT_TRUE(after) << after.describe();
  auto at = second->position();
  EXPECT_TRUE(at) << at.error().describe();
}

TEST(DeviceLock, ASecondStageOnTheSameSerialPortIsRefusedNamingTheHolder) {
  int controller = -1, port = -1;
  char name[256] = {};
  ASSERT_EQ(::openpty(&controller, &port, name, nullptr, nullptr), 0);
  const auto settings = axes({{"device", name}, {"baud", 115200}});
  auto first = make_stage(settings, true);
  ASSERT_TRUE(first);
  const Status connected = first->connect();
  ASSERT_TRUE(connected) << connected.describe();

  auto second = make_stage(settings, true);
  ASSERT_TRUE(second);
  const Status refused = second->connect();
  ASSERT_FALSE(refused) << "two stages drive " << name << " at once";
  EXPECT_STREQ(to_string(refused.error().code), "in use") << refused.describe();
  EXPECT_NE(refused.error().message.find(name), std::string::npos) << refused.describe();
  EXPECT_NE(refused.error().message.find(in_use_by_us()), std::string::npos) << refused.describe();

  first.reset();
  const Status after = second->connect();
  EXPECT_TRUE(after) << after.describe();
  second.reset();
  ::close(port);
  ::close(controller);
}

}  // namespace
}  // namespace vdrig::rig

#endif  // VDRIG_HAVE_MODBUS

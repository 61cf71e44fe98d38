// `vdrig rig ...` and `vdrig capture` as a user runs them, against the independent Modbus peer
// (tests/rig/modbus_drive_peer.py, python3-pymodbus) with the simulated camera.
#include <gtest/gtest.h>
#include <unistd.h>

#include "test_support.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/modbus_peer.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using test::ModbusPeer;

/// The peer's drives as a modbus-tcp stage (fast profile: the self-test's 5 deg moves take about 0.2 s) paired with
/// the small simulated camera.
json peer_rig_config(int port, const char* word_order = "high-first") {
  json config = testing::small_sim_config();
  auto axis = [](int unit, double lo, double hi) {
    return json{{"unit", unit},
                {"counts_per_degree", 1000},
                {"min_deg", lo},
                {"max_deg", hi},
                {"max_speed_deg_s", 90},
                {"accel_deg_s2", 900},
                {"in_position_window_deg", 0.01}};
  };
  config["stage"] = {{"backend", "modbus-tcp"},  {"host", "127.0.0.1"},       {"port", port},
                     {"word_order", word_order}, {"response_timeout_s", 0.2}, {"poll_interval_s", 0.01},
                     {"move_timeout_s", 1.0},    {"home_timeout_s", 2.0},     {"pan", axis(1, -180, 180)},
                     {"tilt", axis(2, -5, 85)}};
  config.erase("light");
  return config;
}

class RigCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (testing::vdrig_cli().empty()) GTEST_SKIP() << "VDRIG_CLI_PATH not set";
  }
  /// Starts the peer (skips when pymodbus is absent) and writes the rig config for it.
  void start_peer(const std::string& peer_args = "", const char* word_order = "high-first") {
    if (const std::string why = test::modbus_peer_unavailable(); !why.empty()) GTEST_SKIP() << why;
    peer_ = std::make_unique<ModbusPeer>(peer_args);
    ASSERT_GT(peer_->port(), 0) << "the pymodbus peer did not start";
    testing::write_text(rig_file_, peer_rig_config(peer_->port(), word_order).dump(2));
  }
  /// Faster axes than the bring-up tests': 16 views round the whole pan range in a few seconds.
  void write_fast_capture_config() {
    json config = peer_rig_config(peer_->port());
    for (const char* axis : {"pan", "tilt"}) {
      config["stage"][axis]["max_speed_deg_s"] = 720;
      config["stage"][axis]["accel_deg_s2"] = 7200;
    }
    testing::write_text(rig_file_, config.dump(2));
  }
  testing::ProcessRun vdrig(std::vector<std::string> args, double timeout_s = 60.0) {
    args.insert(args.begin(), testing::vdrig_cli());
    return testing::run_process(args, {timeout_s});
  }
  vdrig::test::TempDir dir_{"rig_cli"};
  fs::path rig_file_ = dir_.path() / "rig.json";
  std::string runtime_dir_ = (dir_.path() / "run").string();
  std::unique_ptr<ModbusPeer> peer_;
};

TEST_F(RigCli, DevicesListsEveryKindAndSaysNoneFound) {
  const auto r = vdrig({"rig", "devices"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  for (const char* kind : {"V4L2 cameras:", "libcamera cameras:", "USB PTP still cameras:", "gphoto2 cameras",
                           "serial ports", "GPIO chips"})
    EXPECT_NE(r.out.find(kind), std::string::npos) << kind << " missing from:\n" << r.out;
}

TEST_F(RigCli, CheckListsEveryProblemAtOnce) {
  json config = peer_rig_config(502);
  config["stage"].erase("host");
  config["stage"]["word_order"] = "middle-first";
  config["stage"]["pan"]["max_speed_deg_s"] = 10000;
  config["stage"]["pan"]["counts_per_degree"] = 1e6;
  config["camera"] = {{"backend", "no-such-camera"}};
  testing::write_text(rig_file_, config.dump(2));
  const auto r = vdrig({"rig", "check", rig_file_.string()});
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  for (const char* problem : {"host", "word_order", "32-bit profile velocity", "unknown camera backend"})
    EXPECT_NE(r.out.find(problem), std::string::npos) << problem << " not reported:\n" << r.out;
}

// Issue 23: misspelt top-level keys, a "lock" that is not a name, unknown keys in the simulator's device sections
// and a repeated key all passed as "config valid". Each is now a problem, all listed in one run.
TEST_F(RigCli, CheckNamesMisspeltTopLevelKeysAndRepeatedKeys) {
  json config = peer_rig_config(502);
  config["geomtry"] = {{"distance_mm", 2000}};
  config["ligth"] = {{"backend", "sim"}};
  config["simm"] = {{"scene", "checkerboard"}};
  config["lock"] = 5;
  config["camera"]["exposure_s"] = 0.01;  // the sim camera's section holds only its backend
  std::string text = config.dump(2);
  const std::string host = "\"host\": \"127.0.0.1\"";
  ASSERT_NE(text.find(host), std::string::npos) << text;
  text.replace(text.find(host), host.size(), host + ",\n    \"host\": \"10.0.0.9\"");
  testing::write_text(rig_file_, text);
  const auto r = vdrig({"rig", "check", rig_file_.string()});
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_EQ(r.out.find("config valid"), std::string::npos) << r.out;
  for (const char* problem :
       {"unknown top-level key \"geomtry\"", "unknown top-level key \"ligth\"", "unknown top-level key \"simm\"",
        "\"lock\" must be", "unknown setting \"exposure_s\"", "duplicate key \"host\" in stage"})
    EXPECT_NE(r.out.find(problem), std::string::npos) << problem << " not reported:\n" << r.out;
  // A command that drives the rig refuses the file outright, naming the repeated key.
  const auto position = vdrig({"rig", "position", "--rig", rig_file_.string()});
  EXPECT_EQ(position.exit_code, 2) << position.out << position.err;
  EXPECT_NE(position.err.find("duplicate key \"host\" in stage"), std::string::npos) << position.err;
}

// Issue 23: the rig lock lived in the runtime folder, so a vdrigd or CLI started with another one drove the same
// drive at once. Held here (as a vdrigd holds its rig), the drive refuses both, naming this process.
TEST_F(RigCli, ADriveHeldByOneProcessRefusesOthersWhateverTheirRuntimeFolder) {
  start_peer();
  if (IsSkipped()) return;
  rig::BackendRegistry registry;
  rig::register_hardware_backends(registry);
  sim::register_backends(registry);
  auto held = registry.make_rig(peer_rig_config(peer_->port()));
  ASSERT_TRUE(held) << held.error().describe();
  const std::string by_us = "is in use by PID " + std::to_string(::getpid());
  const std::string drive = "127.0.0.1:" + std::to_string(peer_->port());

  const auto cli = vdrig({"rig", "position", "--rig", rig_file_.string()});  // the default runtime folder
  EXPECT_EQ(cli.exit_code, 1) << cli.out << cli.err;
  EXPECT_NE(cli.err.find(drive + " " + by_us), std::string::npos) << cli.err;

  const auto daemon = testing::run_process(
      {testing::vdrigd_exe(), "--runtime-dir", (dir_.path() / "other-run").string(), "--sessions-dir",
       (dir_.path() / "sessions").string(), "--rig", rig_file_.string(), "--log-level", "warn"},
      {10.0});
  EXPECT_FALSE(daemon.timed_out) << "vdrigd served a drive another process drives";
  EXPECT_EQ(daemon.exit_code, 2) << daemon.out << daemon.err;
  EXPECT_NE(daemon.err.find(drive + " " + by_us), std::string::npos) << daemon.err;

  held = make_error(ErrorCode::kCancelled, "released");  // the rig's end frees the drive
  const auto again = vdrig({"rig", "position", "--rig", rig_file_.string(), "--runtime-dir", runtime_dir_});
  EXPECT_EQ(again.exit_code, 0) << again.out << again.err;
}

TEST_F(RigCli, CheckPrintsEffectiveSettingsWithDefaultsAndRegisterMap) {
  testing::write_text(rig_file_, peer_rig_config(502).dump(2));
  const auto r = vdrig({"rig", "check", rig_file_.string()});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("\"retries\": 2"), std::string::npos) << r.out;                        // a default
  EXPECT_NE(r.out.find("\"profile_velocity_counts_s\": 90000"), std::string::npos) << r.out;  // a derived unit
  EXPECT_NE(r.out.find("\"actual_position\": 8"), std::string::npos) << r.out;                // the register map
  EXPECT_NE(r.out.find("config valid"), std::string::npos) << r.out;
}

TEST_F(RigCli, SelfTestPassesAgainstTheIndependentPeer) {
  start_peer();
  if (IsSkipped()) return;
  const auto r = vdrig({"rig", "check", rig_file_.string(), "--self-test", "--runtime-dir", runtime_dir_});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("self-test passed"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("FAIL"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("PASS  frame at"), std::string::npos) << r.out;
}

TEST_F(RigCli, SelfTestCatchesAWordOrderMismatch) {
  start_peer("--word-order high-first", "low-first");
  if (IsSkipped()) return;
  const auto r = vdrig({"rig", "check", rig_file_.string(), "--self-test", "--runtime-dir", runtime_dir_});
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("FAIL  move pan"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("word_order"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("self-test FAILED"), std::string::npos) << r.out;
}

// The README's bring-up steps on the simulator: `vdrig rig check --self-test` passes (moves timed against the profile
// scaled by time_scale), and `vdrig rig move` then `vdrig rig position` read the same position when the "sim" section
// names a state file; without one, position says that it is not kept.
TEST_F(RigCli, SimulatedRigSelfTestAndPositionAcrossCommands) {
  json config = testing::small_sim_config();
  testing::write_text(rig_file_, config.dump(2));
  const auto checked = vdrig({"rig", "check", rig_file_.string(), "--self-test"});
  EXPECT_EQ(checked.exit_code, 0) << checked.out << checked.err;
  EXPECT_NE(checked.out.find("self-test passed"), std::string::npos) << checked.out;

  const auto forgotten = vdrig({"rig", "position", "--rig", rig_file_.string()});
  ASSERT_EQ(forgotten.exit_code, 0) << forgotten.out << forgotten.err;
  EXPECT_NE(forgotten.out.find("not kept"), std::string::npos) << forgotten.out;

  config["sim"]["state_file"] = (dir_.path() / "stage_state.json").string();
  testing::write_text(rig_file_, config.dump(2));
  const auto moved = vdrig({"rig", "move", "--rig", rig_file_.string(), "--pan", "10", "--tilt", "20"});
  ASSERT_EQ(moved.exit_code, 0) << moved.out << moved.err;
  const auto read_back = vdrig({"rig", "position", "--rig", rig_file_.string()});
  ASSERT_EQ(read_back.exit_code, 0) << read_back.out << read_back.err;
  EXPECT_NE(read_back.out.find("pan 10.0000 deg  tilt 20.0000 deg"), std::string::npos) << read_back.out;
  EXPECT_EQ(read_back.out.find("not kept"), std::string::npos) << read_back.out;
}

TEST_F(RigCli, HomeMovePositionAndShoot) {
  start_peer();
  if (IsSkipped()) return;
  const std::vector<std::string> common = {"--rig", rig_file_.string(), "--runtime-dir", runtime_dir_};
  auto run = [&](std::vector<std::string> args) {
    args.insert(args.end(), common.begin(), common.end());
    return vdrig(args);
  };
  const auto homed = run({"rig", "home"});
  ASSERT_EQ(homed.exit_code, 0) << homed.out << homed.err;
  const auto moved = run({"rig", "move", "--pan", "12.5", "--tilt", "30"});
  ASSERT_EQ(moved.exit_code, 0) << moved.out << moved.err;
  EXPECT_NE(moved.out.find("pan 12.5000 deg  tilt 30.0000 deg"), std::string::npos) << moved.out;
  const auto at = run({"rig", "position"});
  ASSERT_EQ(at.exit_code, 0) << at.out << at.err;
  EXPECT_NE(at.out.find("pan 12.5000 deg  tilt 30.0000 deg"), std::string::npos) << at.out;
  const fs::path png = dir_.path() / "frame.png";
  const auto shot = run({"rig", "shoot", "--exposure", "0.01", "--out", png.string()});
  ASSERT_EQ(shot.exit_code, 0) << shot.out << shot.err;
  EXPECT_TRUE(fs::exists(png));
  // Out of the tilt limits: a usage error, nothing moves.
  const auto far = run({"rig", "move", "--pan", "0", "--tilt", "120"});
  EXPECT_NE(far.exit_code, 0) << far.out << far.err;
}

TEST_F(RigCli, CaptureWithTheSimulatedCameraAgainstThePeer) {
  start_peer();
  if (IsSkipped()) return;
  write_fast_capture_config();
  const fs::path session = dir_.path() / "S";
  const auto r = vdrig({"capture", "--rig", rig_file_.string(), "--scheme", "latlong:2", "--bracket", "fixed:0.01",
                        "--out", session.string(), "--reserve-mb", "0", "--runtime-dir", runtime_dir_},
                       120.0);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("100 %"), std::string::npos) << r.out;
  auto reopened = Session::open(session);
  ASSERT_TRUE(reopened) << reopened.error().describe();
  EXPECT_EQ(reopened->completed_view_count(), static_cast<int>(reopened->manifest().views.size()));
  // The peer's drives stand where the last view put them.
  EXPECT_FALSE(peer_->moving(1));
  EXPECT_FALSE(peer_->moving(2));
}

TEST_F(RigCli, CaptureFailingOnADriveFaultResumesWithNoViewLostOrDoubled) {
  start_peer();
  if (IsSkipped()) return;
  write_fast_capture_config();
  // The pan drive starts refusing commands while the first view's move runs: that move ends, the next is refused
  // on every retry, and the capture stops with the fault.
  ASSERT_TRUE(peer_->command("on_move 0.02 refuse 1"));
  const fs::path session = dir_.path() / "S";
  const auto failed = vdrig({"capture", "--rig", rig_file_.string(), "--scheme", "latlong:2", "--bracket", "fixed:0.01",
                             "--out", session.string(), "--reserve-mb", "0", "--runtime-dir", runtime_dir_,
                             "--device-attempts", "2", "--backoff-s", "0.01"},
                            60.0);
  ASSERT_EQ(failed.exit_code, 1) << failed.out << failed.err;
  EXPECT_NE(failed.err.find("pan drive (unit 1"), std::string::npos) << failed.err;
  EXPECT_NE(failed.err.find("failed 2 times"), std::string::npos) << "--device-attempts 2:\n" << failed.err;
  EXPECT_NE(failed.out.find("vdrig capture --resume " + session.string()), std::string::npos) << failed.out;
  {
    auto partial = Session::open(session);
    ASSERT_TRUE(partial) << partial.error().describe();
    EXPECT_LT(partial->completed_view_count(), static_cast<int>(partial->manifest().views.size()));
  }
  ASSERT_TRUE(peer_->command("clear"));
  const auto resumed =
      vdrig({"capture", "--resume", session.string(), "--reserve-mb", "0", "--runtime-dir", runtime_dir_}, 60.0);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.out << resumed.err;
  auto done = Session::open(session);
  ASSERT_TRUE(done) << done.error().describe();
  EXPECT_EQ(done->completed_view_count(), static_cast<int>(done->manifest().views.size()));
  // One frame file per view and exposure: nothing captured twice, nothing missing.
  size_t frames = 0;
  for (const auto& e : fs::recursive_directory_iterator(session / "frames"))
    frames += e.is_regular_file() && e.path().extension() != ".tmp";
  EXPECT_EQ(frames, done->manifest().views.size());
}

}  // namespace
}  // namespace vdrig::capture

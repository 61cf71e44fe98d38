// One capturer per session and one process per rig. While this process holds a session's lock, `vdrig capture
// --resume` and vdrigd's `resume` are refused with "session ... is in use by PID <ours>" and capture nothing; a
// holder killed with SIGKILL leaves a lock the next capture takes. Likewise a rig named by its config's "lock":
// held here, the CLI's capture and vdrigd's start on it are refused with the holder's PID.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <functional>
#include <thread>

#include "sim_session.hpp"
#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/process_lock.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

/// A small planned session (no views captured) in `dir`; returns its view count.
int create_session(const fs::path& dir, const json& rig_config) {
  auto manifest = testing::create_sim_session(dir, rig_config);
  EXPECT_TRUE(manifest) << manifest.error().describe();
  return manifest ? static_cast<int>(manifest->views.size()) : 0;
}

/// Forks a child that holds the lock `take` returns until it is killed; its PID (-1 if it could not take it).
pid_t child_holding(const std::function<bool()>& take) {
  int ready[2];
  if (::pipe(ready) != 0) return -1;
  const pid_t child = ::fork();
  if (child == 0) {
    const char b = take() ? 1 : 0;
    [[maybe_unused]] const ssize_t n = ::write(ready[1], &b, 1);
    ::pause();
    ::_exit(0);
  }
  char b = 0;
  const bool ok = ::read(ready[0], &b, 1) == 1 && b == 1;
  ::close(ready[0]);
  ::close(ready[1]);
  if (!ok && child > 0) {
    ::kill(child, SIGKILL);
    ::waitpid(child, nullptr, 0);
    return -1;
  }
  return child;
}

std::string in_use_by_us() { return "in use by PID " + std::to_string(::getpid()); }

TEST(ProcessLock, SecondHolderIsRefusedWithThePidAndAKilledHolderLeavesNoStaleLock) {
  vdrig::test::TempDir dir("lock_unit");
  fs::create_directories(dir.path());
  const fs::path file = dir.path() / "x.lock";
  {
    auto first = ProcessLock::acquire(file, "thing X");
    ASSERT_TRUE(first) << first.error().describe();
    auto second = ProcessLock::acquire(file, "thing X");  // a new open file: conflicts also within one process
    ASSERT_FALSE(second);
    EXPECT_EQ(second.error().message, "thing X is " + in_use_by_us());
  }
  // Released with its holder.
  EXPECT_TRUE(ProcessLock::acquire(file, "thing X"));

  // A child takes the lock and is SIGKILLed: the kernel releases it.
  std::optional<ProcessLock> in_child;
  const pid_t child = child_holding([&] {
    auto held = ProcessLock::acquire(file, "thing X");
    if (held) in_child = std::move(held.value());
    return in_child.has_value();
  });
  ASSERT_GT(child, 0);
  auto refused = ProcessLock::acquire(file, "thing X");
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().message, "thing X is in use by PID " + std::to_string(child));
  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
  EXPECT_TRUE(ProcessLock::acquire(file, "thing X"));
}

TEST(SessionLock, CliResumeIsRefusedWhileAnotherProcessCapturesAndRunsOnceTheHolderIsKilled) {
  vdrig::test::TempDir root("lock_cli");
  const fs::path session_dir = root.path() / "S";
  const int views = create_session(session_dir, testing::small_sim_config());
  const std::string cli = testing::vdrig_cli();
  ASSERT_FALSE(cli.empty());
  const std::vector<std::string> resume = {cli, "capture", "--resume", session_dir.string(), "--reserve-mb", "0"};
  {
    auto held = lock_session(session_dir);
    ASSERT_TRUE(held) << held.error().describe();
    const auto r = testing::run_process(resume);
    EXPECT_NE(r.exit_code, 0) << r.out << r.err;
    EXPECT_NE(r.err.find("session " + session_dir.string() + " is " + in_use_by_us()), std::string::npos)
        << "stderr: " << r.err;
    auto s = Session::open(session_dir);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->completed_view_count(), 0) << "the refused process captured views";
  }
  // A holder that dies by SIGKILL leaves nothing stale.
  std::optional<ProcessLock> in_child;
  const pid_t child = child_holding([&] {
    auto held = lock_session(session_dir);
    if (held) in_child = std::move(held.value());
    return in_child.has_value();
  });
  ASSERT_GT(child, 0) << "the child could not take the lock";
  {
    const auto r = testing::run_process(resume);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find("in use by PID " + std::to_string(child)), std::string::npos) << "stderr: " << r.err;
  }
  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
  const auto r = testing::run_process(resume);
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  auto s = Session::open(session_dir);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->completed_view_count(), views);
}

TEST(SessionLock, DaemonResumeIsRefusedWhileAnotherProcessCaptures) {
  vdrig::test::TempDir root("lock_daemon");
  const int views = create_session(root.path() / "sessions" / "S", testing::small_sim_config());
  Daemon daemon(testing::sim_daemon_config(root.path()));
  ASSERT_TRUE(daemon.start());
  Status loop;
  std::thread thread([&] { loop = daemon.run(); });
  const int fd = testing::connect_unix(daemon.socket_path());
  ASSERT_GE(fd, 0);
  std::string buf;
  {
    auto held = lock_session(root.path() / "sessions" / "S");
    ASSERT_TRUE(held);
    const json reply = testing::request(fd, buf, {{"cmd", "resume"}, {"session", "S"}});
    EXPECT_FALSE(reply.value("ok", true)) << reply.dump();
    EXPECT_NE(reply.value("error", "").find(in_use_by_us()), std::string::npos) << reply.dump();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    auto s = Session::open(root.path() / "sessions" / "S");
    ASSERT_TRUE(s);
    EXPECT_EQ(s->completed_view_count(), 0);
  }
  // Released: the daemon resumes it to the end.
  const json reply = testing::request(fd, buf, {{"cmd", "resume"}, {"session", "S"}});
  EXPECT_TRUE(reply.value("ok", false)) << reply.dump();
  for (int i = 0; i < 1000; ++i) {
    const json st = testing::request(fd, buf, {{"cmd", "status"}});
    if (st.value("state", "") != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::close(fd);
  daemon.request_stop();
  thread.join();
  auto s = Session::open(root.path() / "sessions" / "S");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->completed_view_count(), views);
}

TEST(RigLock, ARigIsDrivenByOneProcessWhateverItsRuntimeFolder) {
  vdrig::test::TempDir root("lock_rig");
  fs::create_directories(root.path());
  json rig_config = testing::small_sim_config();
  // Named locks live in one folder for the whole machine: a name of this process's own keeps parallel runs apart.
  const std::string name = "bench-" + std::to_string(::getpid());
  rig_config["lock"] = name;
  const fs::path rig_file = root.path() / "rig.json";
  testing::write_text(rig_file, rig_config.dump(2));

  auto held = lock_rig(rig_config);
  ASSERT_TRUE(held) << held.error().describe();
  ASSERT_TRUE(held->has_value());
  const std::string cli = testing::vdrig_cli();
  // The CLI with its default runtime folder, vdrigd with one of its own: both see the lock.
  const auto capture =
      testing::run_process({cli, "capture", "--rig", rig_file.string(), "--scheme", "latlong:2", "--bracket",
                            "fixed:0.01", "--out", (root.path() / "S").string(), "--reserve-mb", "0"});
  EXPECT_NE(capture.exit_code, 0) << capture.out << capture.err;
  EXPECT_NE(capture.err.find("rig " + name + " is " + in_use_by_us()), std::string::npos) << "stderr: " << capture.err;
  EXPECT_FALSE(fs::exists(root.path() / "S" / "journal.jsonl") && Session::open(root.path() / "S") &&
               Session::open(root.path() / "S")->completed_view_count() > 0)
      << "the refused process captured";

  const auto daemon =
      testing::run_process({testing::vdrigd_exe(), "--runtime-dir", (root.path() / "run").string(), "--sessions-dir",
                            (root.path() / "sessions").string(), "--rig", rig_file.string(), "--log-level", "warn"},
                           {10.0});
  EXPECT_FALSE(daemon.timed_out) << "vdrigd served a rig another process drives";
  EXPECT_EQ(daemon.exit_code, 2);
  EXPECT_NE(daemon.err.find("rig " + name + " is " + in_use_by_us()), std::string::npos) << "stderr: " << daemon.err;

  // Released: the CLI drives it.
  held.value().reset();
  const auto again =
      testing::run_process({cli, "capture", "--rig", rig_file.string(), "--scheme", "latlong:2", "--bracket",
                            "fixed:0.01", "--out", (root.path() / "S2").string(), "--reserve-mb", "0"});
  EXPECT_EQ(again.exit_code, 0) << again.out << again.err;
  // Without a "lock", a rig is locked by its devices (the hardware backends), not by name; the simulator drives none.
  EXPECT_FALSE(rig_lock_name(testing::small_sim_config()));
  EXPECT_FALSE(rig_lock_name(json{{"stage", {{"backend", "modbus-rtu"}, {"device", "/dev/ttyUSB0"}}}}));
}

}  // namespace
}  // namespace vdrig::capture

// vdrigd as a careful neighbour: it creates only what it owns (an existing shared runtime folder keeps its mode; a
// regular file at the socket path is refused and kept; a stale socket is replaced), refuses an invalid rig config
// at start (exit 2, with the reason), serves clients round-robin (one pipelining client does not hold up another),
// lists a damaged session folder as damaged instead of failing `list-sessions`, and a refused client is told why;
// idle connections are closed and one uid cannot take every place, so idle sockets cannot lock everyone out.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>

#include <chrono>
#include <thread>

#include "sim_session.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/plan.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

using testing::sim_daemon_config;

/// A plan on the small simulated rig (no session written).
Manifest small_plan(const std::string& scheme) {
  auto manifest = testing::plan_sim(testing::small_sim_config(), scheme);
  EXPECT_TRUE(manifest) << manifest.error().describe();
  return manifest.value();
}

/// A daemon serving on its own thread for the scope.
class Running {
 public:
  explicit Running(DaemonConfig config) : daemon_(std::move(config)) {
    started_ = daemon_.start();
    if (started_) thread_ = std::thread([this] { loop_ = daemon_.run(); });
  }
  ~Running() {
    daemon_.request_stop();
    if (thread_.joinable()) thread_.join();
  }
  const Status& started() const { return started_; }
  Daemon& daemon() { return daemon_; }

 private:
  Daemon daemon_;
  Status started_, loop_;
  std::thread thread_;
};

TEST(VdrigdRuntimeDir, AnExistingSharedFolderKeepsItsModeAndACreatedOneIs0770) {
  vdrig::test::TempDir root("rt_mode");
  fs::create_directories(root.path() / "run");
  ASSERT_EQ(::chmod((root.path() / "run").c_str(), 01777), 0);
  {
    Running d(sim_daemon_config(root.path()));
    ASSERT_TRUE(d.started()) << d.started().describe();
    struct stat st {};
    ASSERT_EQ(::stat((root.path() / "run").c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 07777, 01777u) << "vdrigd changed the mode of a folder it did not create";
  }
  vdrig::test::TempDir fresh("rt_fresh");
  Running d(sim_daemon_config(fresh.path()));
  ASSERT_TRUE(d.started()) << d.started().describe();
  struct stat st {};
  ASSERT_EQ(::stat((fresh.path() / "run").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0770u);
}

TEST(VdrigdRuntimeDir, ARegularFileAtTheSocketPathIsRefusedAndKept) {
  vdrig::test::TempDir root("rt_file");
  fs::create_directories(root.path() / "run");
  testing::write_text(root.path() / "run" / "vdrigd.sock", "not a socket\n");
  Daemon daemon(sim_daemon_config(root.path()));
  const Status s = daemon.start();
  ASSERT_FALSE(s) << "vdrigd started over a regular file";
  EXPECT_NE(s.error().message.find("not a socket"), std::string::npos) << s.describe();
  EXPECT_TRUE(fs::is_regular_file(root.path() / "run" / "vdrigd.sock"));
}

TEST(VdrigdRuntimeDir, AStaleSocketIsReplaced) {
  vdrig::test::TempDir root("rt_stale");
  fs::create_directories(root.path() / "run");
  {  // bound, never listened on and closed: a connect is refused
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string path = (root.path() / "run" / "vdrigd.sock").string();
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    ::close(fd);
  }
  Running d(sim_daemon_config(root.path()));
  ASSERT_TRUE(d.started()) << d.started().describe();
  const int fd = testing::connect_unix(d.daemon().socket_path());
  ASSERT_GE(fd, 0);
  std::string buf;
  EXPECT_TRUE(testing::request(fd, buf, {{"cmd", "status"}}).value("ok", false));
  ::close(fd);
}

TEST(VdrigdStart, AnInvalidRigConfigExits2WithTheReason) {
  vdrig::test::TempDir root("bad_rig");
  fs::create_directories(root.path());
  const fs::path rig = root.path() / "rig.json";
  testing::write_text(rig, R"({"stage": {"backend": "no-such-stage"}, "camera": {"backend": "sim"}})");
  const auto r = testing::run_process({testing::vdrigd_exe(), "--runtime-dir", (root.path() / "run").string(),
                                       "--sessions-dir", (root.path() / "sessions").string(), "--rig", rig.string()},
                                      {10.0});
  EXPECT_FALSE(r.timed_out) << "vdrigd served with an invalid rig config";
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("no-such-stage"), std::string::npos) << "stderr: " << r.err;
  EXPECT_EQ(r.err.find("listening"), std::string::npos) << "stderr: " << r.err;

  testing::write_text(rig, R"({"sim": {"scene": "patchwork", "camera": {"width": -5}}, "stage": {"backend": "sim"},
                               "camera": {"backend": "sim"}})");
  const auto r2 = testing::run_process({testing::vdrigd_exe(), "--runtime-dir", (root.path() / "run").string(),
                                        "--sessions-dir", (root.path() / "sessions").string(), "--rig", rig.string()},
                                       {10.0});
  EXPECT_FALSE(r2.timed_out) << "vdrigd served with invalid backend settings";
  EXPECT_EQ(r2.exit_code, 2) << r2.err;
  EXPECT_NE(r2.err.find("camera: \"width\" = -5 is outside"), std::string::npos) << "stderr: " << r2.err;
  EXPECT_EQ(r2.err.find("listening"), std::string::npos) << "stderr: " << r2.err;
}

TEST(VdrigdFairness, OnePipeliningClientDoesNotHoldUpAnother) {
  vdrig::test::TempDir root("fair");
  // Sessions to list make each list-sessions take a while.
  const Manifest manifest = small_plan("latlong:4");
  for (int i = 0; i < 10; ++i)
    ASSERT_TRUE(Session::create(root.path() / "sessions" / ("s" + std::to_string(i)), manifest));

  Running d(sim_daemon_config(root.path()));
  ASSERT_TRUE(d.started()) << d.started().describe();
  const int greedy = testing::connect_unix(d.daemon().socket_path());
  const int other = testing::connect_unix(d.daemon().socket_path());
  ASSERT_GE(greedy, 0);
  ASSERT_GE(other, 0);
  constexpr int kRequests = 1500;
  std::string pipelined;
  for (int i = 0; i < kRequests; ++i)
    pipelined += R"({"cmd":"list-sessions"})"
                 "\n";
  const auto t0 = Clock::now();
  // The greedy client writes everything (from a thread: the daemon's replies fill its socket) and reads later.
  std::thread writer([&] { testing::send_all(greedy, pipelined); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // its requests are queued first
  std::string buf;
  const auto t1 = Clock::now();
  const json status = testing::request(other, buf, {{"cmd", "status"}}, 60000);
  const double other_wait_s = std::chrono::duration<double>(Clock::now() - t1).count();
  EXPECT_TRUE(status.value("ok", false)) << status.dump();
  // Drain the greedy client's replies.
  std::string gbuf;
  int replies = 0;
  while (replies < kRequests) {
    if (!testing::read_line(greedy, gbuf, 60000)) break;
    ++replies;
  }
  writer.join();
  const double greedy_s = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_EQ(replies, kRequests);
  EXPECT_LT(other_wait_s, greedy_s / 10) << "status waited " << other_wait_s << " s behind " << kRequests
                                         << " pipelined requests that took " << greedy_s << " s";
  ::close(greedy);
  ::close(other);
}

TEST(VdrigdListSessions, ADamagedSessionIsListedAsDamagedAndTheOthersStillAre) {
  vdrig::test::TempDir root("damaged");
  const Manifest manifest = small_plan("latlong:2");
  const fs::path sessions = root.path() / "sessions";
  ASSERT_TRUE(Session::create(sessions / "good", manifest));
  ASSERT_TRUE(Session::create(sessions / "bad_manifest", manifest));
  testing::write_text(SessionLayout(sessions / "bad_manifest").manifest_file(), "{ not json");
  ASSERT_TRUE(Session::create(sessions / "bad_journal", manifest));
  testing::write_text(SessionLayout(sessions / "bad_journal").journal_file(), "{\"type\":\"frame\"\n");
  ASSERT_TRUE(Session::create(sessions / "bad_line", manifest));
  testing::write_text(SessionLayout(sessions / "bad_line").journal_file(), "garbage\n");
  // A wrong-typed field: it once threw out of Session::open and failed the whole listing.
  ASSERT_TRUE(Session::create(sessions / "bad_type", manifest));
  testing::write_text(SessionLayout(sessions / "bad_type").journal_file(),
                      "{\"type\":\"view_complete\",\"view\":[0]}\n");

  Running d(sim_daemon_config(root.path()));
  ASSERT_TRUE(d.started()) << d.started().describe();
  const int fd = testing::connect_unix(d.daemon().socket_path());
  ASSERT_GE(fd, 0);
  std::string buf;
  const json reply = testing::request(fd, buf, {{"cmd", "list-sessions"}});
  ::close(fd);
  ASSERT_TRUE(reply.value("ok", false)) << reply.dump();
  std::map<std::string, json> by_name;
  for (const auto& s : reply.at("sessions")) by_name[s.value("session", "")] = s;
  ASSERT_TRUE(by_name.count("good")) << reply.dump();
  EXPECT_FALSE(by_name["good"].contains("damaged"));
  EXPECT_EQ(by_name["good"].value("views_total", 0), static_cast<int>(manifest.views.size()));
  EXPECT_TRUE(by_name.count("bad_type")) << reply.dump();  // listed, damaged or not (its parser may skip the line)
  for (const char* bad : {"bad_manifest", "bad_line"}) {
    ASSERT_TRUE(by_name.count(bad)) << bad << " not listed: " << reply.dump();
    EXPECT_TRUE(by_name[bad].value("damaged", false)) << by_name[bad].dump();
    EXPECT_FALSE(by_name[bad].value("reason", "").empty()) << by_name[bad].dump();
  }
}

TEST(VdrigdRefusal, ARefusedClientIsToldWhy) {
  vdrig::test::TempDir root("refused");
  DaemonConfig config = sim_daemon_config(root.path());
  config.allowed_uid = ::geteuid() + 4242;
  config.allowed_gid = ::getegid() + 4242;
  Running d(config);
  ASSERT_TRUE(d.started()) << d.started().describe();
  for (int i = 0; i < 10; ++i) {
    const auto r = testing::run_process(
        {testing::vdrig_cli(), "session", "status", "--runtime-dir", (root.path() / "run").string()}, {20.0});
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find("peer not allowed"), std::string::npos) << "stderr: " << r.err;
    EXPECT_EQ(r.err.find("send to daemon failed"), std::string::npos) << "stderr: " << r.err;
  }
}

/// The first line the daemon sends on `fd` as JSON (discarded when there is none within `timeout_ms`).
json first_reply(int fd, int timeout_ms = 5000) {
  std::string buf;
  const auto line = testing::read_line(fd, buf, timeout_ms);
  return line ? json::parse(*line, nullptr, false) : json(json::value_t::discarded);
}

// Before: 64 idle sockets locked everyone out (no idle timeout, no per-uid limit) and the CLI called the refusal a
// "device fault". Now a uid's connections beyond its limit are refused as "too many clients", an idle connection is
// told so and closed (freeing its place), a subscribed watcher is not, and the CLI says what happened.
TEST(VdrigdConnections, IdleSocketsCannotLockEveryoneOut) {
  vdrig::test::TempDir root("idle");
  DaemonConfig config = sim_daemon_config(root.path());
  config.max_clients = 8;
  config.max_clients_per_uid = 3;
  // Long enough for the refused CLI below to start and connect while the idle ones still hold their slots: a loaded
  // machine under ASan took more than 1 s to start `vdrig`, found the slots freed and was served.
  config.idle_timeout_s = 4.0;
  Running d(config);
  ASSERT_TRUE(d.started()) << d.started().describe();
  const fs::path socket = d.daemon().socket_path();
  const std::string runtime_dir = (root.path() / "run").string();

  const Clock::time_point opened = Clock::now();
  std::vector<int> idle;
  for (int i = 0; i < 2; ++i) idle.push_back(testing::connect_unix(socket));
  const int watcher = testing::connect_unix(socket);
  ASSERT_TRUE(testing::send_all(watcher, R"({"cmd":"subscribe"})"
                                         "\n"));
  EXPECT_TRUE(first_reply(watcher).value("ok", false));
  for (int fd : idle) ASSERT_GE(fd, 0);

  // The uid's fourth connection: refused, and the CLI reports it as a refusal.
  const int fourth = testing::connect_unix(socket);
  const json refusal = first_reply(fourth);
  EXPECT_EQ(refusal.value("code", ""), "busy") << refusal.dump();
  EXPECT_NE(refusal.value("error", "").find("too many clients of uid"), std::string::npos) << refusal.dump();
  ::close(fourth);
  const auto cli =
      testing::run_process({testing::vdrig_cli(), "session", "status", "--runtime-dir", runtime_dir}, {20.0});
  EXPECT_EQ(cli.exit_code, 1);
  EXPECT_NE(cli.err.find("refused the connection: too many clients"), std::string::npos) << cli.err;
  EXPECT_EQ(cli.err.find("device fault"), std::string::npos) << cli.err;

  // After the idle timeout the idle ones are told and closed; the watcher stays; the CLI is served again.
  for (int fd : idle) {
    const json bye = first_reply(fd, 8000);
    EXPECT_EQ(bye.value("code", ""), "idle_timeout") << bye.dump();
    ::close(fd);
  }
  const double closed_after_s = std::chrono::duration<double>(Clock::now() - opened).count();
  EXPECT_GE(closed_after_s, 3.9);
  EXPECT_LT(closed_after_s, 6.0);
  const auto served =
      testing::run_process({testing::vdrig_cli(), "session", "status", "--runtime-dir", runtime_dir}, {20.0});
  EXPECT_EQ(served.exit_code, 0) << served.err;
  ASSERT_TRUE(testing::send_all(watcher, R"({"cmd":"status"})"
                                         "\n"));
  const json status = first_reply(watcher);
  EXPECT_TRUE(status.value("ok", false) || status.contains("event")) << status.dump();
  ::close(watcher);
}

TEST(VdrigdConnections, LimitsAreValidated) {
  DaemonConfig config = sim_daemon_config("/tmp/unused");
  std::string why;
  config.max_clients_per_uid = 0;
  EXPECT_FALSE(config.is_valid(&why));
  config.max_clients_per_uid = config.max_clients + 1;
  EXPECT_FALSE(config.is_valid(&why));
  EXPECT_NE(why.find("max_clients_per_uid"), std::string::npos) << why;
  config.max_clients_per_uid = 4;
  config.idle_timeout_s = 0.0;
  EXPECT_FALSE(config.is_valid(&why));
  EXPECT_NE(why.find("idle_timeout_s"), std::string::npos) << why;
}

}  // namespace
}  // namespace vdrig::capture

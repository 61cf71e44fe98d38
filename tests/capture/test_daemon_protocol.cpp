// vdrigd's control protocol, in-process: 10,000 malformed or random requests over a few connections are each
// answered with an error (or the connection is closed, for oversized lines) and the daemon keeps serving; then a
// small simulated session is started, followed, paused, resumed and aborted over the socket.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <random>
#include <thread>

#include "vdrig/capture/daemon.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

json small_sim_config() {
  return sim::sim_rig_config(
      {{"scene", "patchwork"},
       {"samples_per_axis", 1},
       {"camera", {{"width", 160}, {"height", 120}, {"fx", 200}, {"fy", 200}, {"cx", 79.5}, {"cy", 59.5}}}});
}

class DaemonFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("vdrigd_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    DaemonConfig config;
    config.runtime_dir = root_ / "run";
    config.sessions_dir = root_ / "sessions";
    config.rig_config = small_sim_config();
    config.make_rig = [](const json& rc) -> Result<rig::Rig> {
      rig::BackendRegistry registry;
      sim::register_backends(registry);
      return registry.make_rig(rc);
    };
    config.capture.disk_reserve_bytes = 0;
    daemon_ = std::make_unique<Daemon>(config);
    const Status s = daemon_->start();
    ASSERT_TRUE(s) << s.describe();
    thread_ = std::thread([this] { loop_status_ = daemon_->run(); });
  }
  void TearDown() override {
    if (daemon_) daemon_->request_stop();
    if (thread_.joinable()) thread_.join();
    EXPECT_TRUE(loop_status_) << loop_status_.describe();
    EXPECT_FALSE(fs::exists(root_ / "run" / "vdrigd.sock"));
    fs::remove_all(root_);
  }

  int connect_client() {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string path = daemon_->socket_path().string();
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0) << std::strerror(errno);
    return fd;
  }

  static bool send_all(int fd, const std::string& bytes) {
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::send(fd, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n <= 0) return false;
      done += static_cast<size_t>(n);
    }
    return true;
  }

  /// Reads one line; nullopt when the connection closed (or nothing came within the timeout).
  static std::optional<std::string> read_line(int fd, std::string& buffer, int timeout_ms = 5000) {
    while (true) {
      const size_t pos = buffer.find('\n');
      if (pos != std::string::npos) {
        std::string line = buffer.substr(0, pos);
        buffer.erase(0, pos + 1);
        return line;
      }
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, timeout_ms) <= 0) return std::nullopt;
      char buf[4096];
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) return std::nullopt;
      buffer.append(buf, static_cast<size_t>(n));
    }
  }

  json request(int fd, std::string& buffer, const json& req) {
    EXPECT_TRUE(send_all(fd, req.dump() + "\n"));
    while (true) {
      auto line = read_line(fd, buffer);
      if (!line) return json{{"closed", true}};
      json j = json::parse(*line, nullptr, false);
      if (j.is_discarded()) return json{{"unparseable", *line}};
      if (!j.contains("event")) return j;  // skip pushed events
    }
  }

  fs::path root_;
  std::unique_ptr<Daemon> daemon_;
  std::thread thread_;
  Status loop_status_;
};

std::string random_message(std::mt19937& rng, int kind) {
  std::uniform_int_distribution<int> byte(0, 255), len(0, 200);
  auto bytes = [&](int n) {
    std::string s;
    for (int i = 0; i < n; ++i) {
      char c = static_cast<char>(byte(rng));
      if (c == '\n') c = ' ';
      s += c;
    }
    return s;
  };
  static const char* cmds[] = {"start",     "pause", "resume", "abort",        "status",
                               "subscribe", "home",  "move",   "list-sessions"};
  const std::string cmd = cmds[rng() % 9];
  switch (kind) {
    case 0:
      return bytes(len(rng));  // random bytes
    case 1: {                  // truncated JSON
      const std::string full = json{{"cmd", cmd}, {"pan_deg", 10}, {"session", "abc"}}.dump();
      return full.substr(0, rng() % full.size());
    }
    case 2: {  // wrong types
      static const char* wrong[] = {R"({"cmd":5})",
                                    R"({"cmd":null})",
                                    R"(["status"])",
                                    R"("status")",
                                    R"(42)",
                                    R"({"cmd":"move","pan_deg":"ten","tilt_deg":5})",
                                    R"({"cmd":"move","pan_deg":1e999,"tilt_deg":5})",
                                    R"({"cmd":"start","session":["x"]})",
                                    R"({"cmd":"start","session":7})",
                                    R"({"cmd":"start","session":"../../etc"})",
                                    R"({"cmd":"start","session":".hidden"})",
                                    R"({"cmd":"start","session":"ok","scheme":"nonsense:3"})",
                                    R"({"cmd":"start","session":"ok2","bracket":"fixed:1,1"})",
                                    R"({"cmd":"status","id":[1]})",
                                    R"({"cmd":"status","extra":1})",
                                    R"({"cmd":"resume","session":"no-such-session"})",
                                    R"({"cmd":"pause"})",
                                    R"({"cmd":"abort"})",
                                    R"({"cmd":"move","pan_deg":9999,"tilt_deg":0})"};
      return wrong[rng() % (sizeof wrong / sizeof wrong[0])];
    }
    case 3:
      return json{{"cmd", "x-" + std::to_string(rng() % 1000)}}.dump();  // unknown command
    default: {                                                           // invalid UTF-8 in a string
      std::string s = R"({"cmd":"status","id":")";
      s += static_cast<char>(0xC3);
      s += static_cast<char>(0x28);
      s += static_cast<char>(0xFF);
      return s + "\"}";
    }
  }
}

TEST_F(DaemonFixture, SocketIsGroupOnlyAndRandomMessagesAllGetErrors) {
  struct stat st {};
  ASSERT_EQ(::stat(daemon_->socket_path().c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);

  const auto t0 = std::chrono::steady_clock::now();
  std::mt19937 rng(7);
  constexpr int kConnections = 5;
  std::vector<int> fds(kConnections);
  std::vector<std::string> buffers(kConnections);
  for (auto& fd : fds) fd = connect_client();
  int errors = 0, closed = 0, oversized_sent = 0;
  for (int i = 0; i < 10000; ++i) {
    const int c = i % kConnections;
    if (i % 997 == 13) {
      // Oversized: more than 64 KiB without a newline. The daemon answers with an error and closes.
      ++oversized_sent;
      send_all(fds[c], std::string(70 * 1024, 'x') + "\n");
      for (;;) {
        auto line = read_line(fds[c], buffers[c]);
        if (!line) break;
        EXPECT_NE(line->find("too_long"), std::string::npos) << *line;
      }
      ++closed;
      ::close(fds[c]);
      fds[c] = connect_client();
      buffers[c].clear();
      continue;
    }
    const std::string msg = random_message(rng, i % 5);
    ASSERT_TRUE(send_all(fds[c], msg + "\n"));
    auto line = read_line(fds[c], buffers[c]);
    ASSERT_TRUE(line) << "no answer to message " << i << ": " << msg;
    const json reply = json::parse(*line, nullptr, false);
    ASSERT_FALSE(reply.is_discarded()) << *line;
    ASSERT_TRUE(reply.contains("ok")) << *line;
    EXPECT_FALSE(reply["ok"].get<bool>()) << "message " << i << " accepted: " << msg << " -> " << *line;
    ++errors;
  }
  EXPECT_EQ(errors + closed, 10000);
  EXPECT_GE(oversized_sent, 10);
  for (int c = 0; c < kConnections; ++c) {
    const json status = request(fds[c], buffers[c], {{"cmd", "status"}, {"id", c}});
    EXPECT_TRUE(status.value("ok", false)) << status.dump();
    EXPECT_EQ(status.value("id", -1), c);
    EXPECT_EQ(status.value("state", ""), "idle");
    ::close(fds[c]);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(seconds, 30.0);
  std::printf("protocol test: %d error replies, %d oversized closes, %.2f s\n", errors, closed, seconds);
}

TEST_F(DaemonFixture, RunsASessionWithPauseResumeAbortAndMoves) {
  const int fd = connect_client();
  std::string buf;
  // Stage control while idle.
  json moved = request(fd, buf, {{"cmd", "move"}, {"pan_deg", 30}, {"tilt_deg", 20}});
  ASSERT_TRUE(moved.value("ok", false)) << moved.dump();
  EXPECT_NEAR(moved["pan_deg"].get<double>(), 30, 1e-6);
  EXPECT_NEAR(moved["tilt_deg"].get<double>(), 20, 1e-6);
  json homed = request(fd, buf, {{"cmd", "home"}});
  ASSERT_TRUE(homed.value("ok", false)) << homed.dump();
  EXPECT_NEAR(homed["tilt_deg"].get<double>(), 0, 1e-6);

  // A session followed to completion through pushed events.
  json sub = request(fd, buf, {{"cmd", "subscribe"}});
  ASSERT_TRUE(sub.value("ok", false));
  json started = request(fd, buf, {{"cmd", "start"}, {"session", "s1"}, {"scheme", "latlong:2"}, {"bracket", "auto"}});
  ASSERT_TRUE(started.value("ok", false)) << started.dump();
  const int total = started["views_total"].get<int>();
  ASSERT_GT(total, 3);
  EXPECT_TRUE(started["route"].contains("planned_time_s"));
  int last_done = -1;
  std::string final_state;
  for (int k = 0; k < 100000 && final_state.empty(); ++k) {
    auto line = read_line(fd, buf);
    ASSERT_TRUE(line) << "event stream ended";
    const json ev = json::parse(*line);
    if (ev.value("event", "") == "progress") {
      EXPECT_GE(ev["views_done"].get<int>(), last_done);
      last_done = ev["views_done"].get<int>();
      EXPECT_EQ(ev["views_total"].get<int>(), total);
    } else if (ev.value("event", "") == "state" && ev["state"] != "running") {
      final_state = ev["state"];
    }
  }
  EXPECT_EQ(final_state, "completed");
  EXPECT_EQ(last_done, total);
  auto s1 = Session::open(root_ / "sessions" / "s1");
  ASSERT_TRUE(s1);
  EXPECT_EQ(s1->completed_view_count(), total);

  // Pause / resume / abort on a larger session.
  json s2 = request(fd, buf,
                    {{"cmd", "start"}, {"session", "s2"}, {"scheme", "spiral:60:4@80"}, {"bracket", "fixed:0.5,0.1"}});
  ASSERT_TRUE(s2.value("ok", false)) << s2.dump();
  json busy = request(fd, buf, {{"cmd", "move"}, {"pan_deg", 0}, {"tilt_deg", 0}});
  EXPECT_EQ(busy.value("code", ""), "busy");
  json paused = request(fd, buf, {{"cmd", "pause"}});
  ASSERT_TRUE(paused.value("ok", false)) << paused.dump();
  json status;
  for (int k = 0; k < 500; ++k) {
    status = request(fd, buf, {{"cmd", "status"}});
    if (status["state"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(status["state"], "paused") << status.dump();
  const int done_at_pause = status["views_done"].get<int>();
  EXPECT_LT(done_at_pause, 60);
  json listed = request(fd, buf, {{"cmd", "list-sessions"}});
  ASSERT_TRUE(listed.value("ok", false));
  EXPECT_EQ(listed["sessions"].size(), 2u);
  json resumed = request(fd, buf, {{"cmd", "resume"}});
  ASSERT_TRUE(resumed.value("ok", false)) << resumed.dump();
  json aborted = request(fd, buf, {{"cmd", "abort"}});
  ASSERT_TRUE(aborted.value("ok", false) || aborted.value("code", "") == "invalid_state") << aborted.dump();
  for (int k = 0; k < 500; ++k) {
    status = request(fd, buf, {{"cmd", "status"}});
    if (status["state"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_TRUE(status["state"] == "aborted" || status["state"] == "completed") << status.dump();
  auto session2 = Session::open(root_ / "sessions" / "s2");
  ASSERT_TRUE(session2);
  EXPECT_GE(session2->completed_view_count(), done_at_pause);
  // Names that escape the sessions folder are refused.
  json bad = request(fd, buf, {{"cmd", "start"}, {"session", "../escape"}});
  EXPECT_FALSE(bad.value("ok", true));
  EXPECT_FALSE(fs::exists(root_ / "escape"));
  ::close(fd);
}

}  // namespace
}  // namespace vdrig::capture

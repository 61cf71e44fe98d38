// vdrigd's control protocol, in-process: 10,000 malformed or random requests over a few connections are each
// answered with an error (or the connection is closed, for oversized lines) and the daemon keeps serving; then a
// small simulated session is started, followed, paused, resumed and aborted over the socket. Peers of another uid
// and gid are refused (SO_PEERCRED) while allowed ones are served.
#include <gtest/gtest.h>

#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>
#include <algorithm>

#include <grp.h>
#include <sys/wait.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <random>
#include <set>
#include <thread>

#include "sim_session.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

using testing::read_line;
using testing::request;
using testing::send_all;

class DaemonFixture : public ::testing::Test {
 protected:
  void SetUp() override { start_daemon(); }
  void TearDown() override { stop_daemon(); }

  /// Starts the in-process daemon on root_; `tweak` adjusts the config first (e.g. the allowed peers).
  void start_daemon(const std::function<void(DaemonConfig&)>& tweak = {}) {
    DaemonConfig config = testing::sim_daemon_config(root_);
    if (tweak) tweak(config);
    daemon_ = std::make_unique<Daemon>(config);
    const Status s = daemon_->start();
    ASSERT_TRUE(s) << s.describe();
    thread_ = std::thread([this] { loop_status_ = daemon_->run(); });
  }
  /// Stops it and checks that its loop ended cleanly and removed the socket.
  void stop_daemon() {
    if (daemon_) daemon_->request_stop();
    if (thread_.joinable()) thread_.join();
    daemon_.reset();
    EXPECT_TRUE(loop_status_) << loop_status_.describe();
    EXPECT_FALSE(fs::exists(root_ / "run" / "vdrigd.sock"));
  }

  int connect_client() {
    const int fd = testing::connect_unix(daemon_->socket_path());
    EXPECT_GE(fd, 0) << std::strerror(errno);
    return fd;
  }

  const test::TempDir root_{"vdrigd"};
  std::unique_ptr<Daemon> daemon_;
  std::thread thread_;
  Status loop_status_;
};

/// A connection the daemon refused: it says why ({"ok": false, "code": "permission_denied"}) and closes, and a
/// request sent afterwards gets no answer.
void expect_refused(int fd) {
  std::string buf;
  const auto first = read_line(fd, buf);
  ASSERT_TRUE(first) << "no refusal line";
  const json reply = json::parse(*first, nullptr, false);
  ASSERT_FALSE(reply.is_discarded()) << *first;
  EXPECT_FALSE(reply.value("ok", true)) << *first;
  EXPECT_EQ(reply.value("code", ""), "permission_denied") << *first;
  (void)send_all(fd, R"({"cmd":"status"})"
                     "\n");
  EXPECT_FALSE(read_line(fd, buf, 2000)) << "a refused connection answered";
}

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

// SO_PEERCRED: a peer whose uid is not the allowed one and whose gid is not the allowed group is refused at accept.
TEST_F(DaemonFixture, RefusesPeersOfAnotherUidAndGid) {
  stop_daemon();
  start_daemon([](DaemonConfig& c) {
    c.allowed_uid = ::geteuid() + 4242;  // neither ours...
    c.allowed_gid = ::getegid() + 4242;  // ...nor our group
  });
  for (int k = 0; k < 20; ++k) {
    const int fd = connect_client();
    ASSERT_GE(fd, 0);
    expect_refused(fd);
    ::close(fd);
  }
  // Nothing was started for the refused peers.
  EXPECT_TRUE(fs::is_empty(root_ / "sessions"));

  // The same process let in through the group rule alone (its uid is still not the allowed one) is served.
  stop_daemon();
  start_daemon([](DaemonConfig& c) {
    c.allowed_uid = ::geteuid() + 4242;
    c.allowed_gid = ::getegid();
  });
  const int fd = connect_client();
  std::string buf;
  const json status = request(fd, buf, {{"cmd", "status"}});
  EXPECT_TRUE(status.value("ok", false)) << status.dump();
  EXPECT_EQ(status.value("state", ""), "idle");
  ::close(fd);
}

// The same against a real process of another uid, while an allowed client (this process) keeps being served. Needs
// root to run a child as another user.
TEST_F(DaemonFixture, RefusesAnotherUserWhileServingTheAllowedOne) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to connect as another uid (setuid in a child)";
  // Let the other user reach the socket through the file system, so SO_PEERCRED is the only gate.
  fs::permissions(root_ / "run", fs::perms::all);
  fs::permissions(daemon_->socket_path(), fs::perms::all);
  const int allowed = connect_client();
  std::string allowed_buf;
  ASSERT_TRUE(request(allowed, allowed_buf, {{"cmd", "subscribe"}}).value("ok", false));
  for (int k = 0; k < 5; ++k) {
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      // Child: become nobody (uid/gid 65534), connect, and report through the exit code what the daemon said.
      if (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(10);
      const int fd = testing::connect_unix(daemon_->socket_path());
      if (fd < 0) ::_exit(11);
      std::string buf;
      const auto line = read_line(fd, buf);
      if (!line) ::_exit(12);
      const json reply = json::parse(*line, nullptr, false);
      if (reply.is_discarded() || reply.value("ok", true) || reply.value("code", "") != "permission_denied")
        ::_exit(13);
      (void)send_all(fd, "{\"cmd\":\"status\"}\n");
      if (read_line(fd, buf, 2000)) ::_exit(14);  // answered after the refusal
      ::_exit(0);
    }
    int wstatus = 0;
    ASSERT_EQ(::waitpid(pid, &wstatus, 0), pid);
    ASSERT_TRUE(WIFEXITED(wstatus));
    EXPECT_EQ(WEXITSTATUS(wstatus), 0) << "child (uid 65534): 10 setuid, 11 connect, 12 no reply, 13 not refused, "
                                          "14 answered after refusal";
    // Meanwhile the allowed connection is still served.
    const json status = request(allowed, allowed_buf, {{"cmd", "status"}, {"id", k}});
    EXPECT_TRUE(status.value("ok", false)) << status.dump();
    EXPECT_EQ(status.value("id", -1), k);
  }
  ::close(allowed);
}

/// The codes docs/protocol.md's "Error codes" table lists (first column, in backticks).
// Plain string code rather than <regex>: GCC 12 warns falsely (-Wmaybe-uninitialized) inside std::regex under ASan.
bool is_snake_case(const std::string& s) {
  if (s.empty() || s.front() == '_' || s.back() == '_' || s.find("__") != std::string::npos) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return (c >= 'a' && c <= 'z') || c == '_'; });
}

std::set<std::string> documented_error_codes() {
  std::ifstream doc(fs::path(VDRIG_SOURCE_DIR) / "docs" / "protocol.md");
  EXPECT_TRUE(doc) << "cannot read docs/protocol.md";
  std::set<std::string> codes;
  std::string line;
  bool in_section = false;
  const std::string row_start = "| `";
  while (std::getline(doc, line)) {
    if (line.rfind("## ", 0) == 0) in_section = line == "## Error codes";
    if (!in_section || line.rfind(row_start, 0) != 0) continue;  // a table row: | `code` | ...
    const size_t end = line.find("` |", row_start.size());
    if (end == std::string::npos) continue;
    const std::string code = line.substr(row_start.size(), end - row_start.size());
    EXPECT_TRUE(codes.insert(code).second) << "listed twice: " << code;
  }
  return codes;
}

// One wire code per ErrorCode, distinct and snake_case, and the protocol document lists exactly the codes sent.
TEST(WireCodes, EveryErrorCodeHasADistinctSnakeCaseCodeAndTheDocsListExactlyTheCodesSent) {
  const ErrorCode all[] = {ErrorCode::kIo,           ErrorCode::kCorrupt,  ErrorCode::kInvalidArgument,
                           ErrorCode::kNotFound,     ErrorCode::kDevice,   ErrorCode::kTimeout,
                           ErrorCode::kDisconnected, ErrorCode::kNoSpace,  ErrorCode::kUnsupported,
                           ErrorCode::kCancelled,    ErrorCode::kInternal, ErrorCode::kInUse};
  // The list above is every ErrorCode: the values are 0..N-1 and N itself is not one (wire_code's fallback).
  for (size_t k = 0; k < std::size(all); ++k) EXPECT_EQ(static_cast<size_t>(all[k]), k);
  EXPECT_STREQ(wire_code(static_cast<ErrorCode>(std::size(all))), "unknown") << "a new ErrorCode: add it here";

  std::set<std::string> sent;
  for (const ErrorCode code : all) {
    const std::string wire = wire_code(code);
    EXPECT_TRUE(is_snake_case(wire)) << wire;
    EXPECT_TRUE(sent.insert(wire).second) << "two ErrorCodes share " << wire;
  }
  EXPECT_EQ(sent.count("invalid_argument"), 1u);
  EXPECT_EQ(sent.count("no_space"), 1u);
  EXPECT_EQ(sent.count("not_found"), 1u);
  for (const std::string& own : protocol_error_codes()) {
    EXPECT_TRUE(is_snake_case(own)) << own;
    EXPECT_TRUE(sent.insert(own).second) << own << " is also an ErrorCode's wire code";
  }
  EXPECT_EQ(documented_error_codes(), sent);
}

}  // namespace
}  // namespace vdrig::capture

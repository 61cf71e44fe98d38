// The web console's API as a client of vdrigd: commands are relayed with the daemon's own validation (the same code
// and text as on its socket), only whitelisted string fields go through, the daemon's subscribe events arrive on
// /api/events as Server-Sent Events (progress, pause, resume), and a daemon that is not there is reported (502, and
// connected:false on the stream) instead of hanging.
#include <gtest/gtest.h>

#include "web_support.hpp"

namespace vdrig::web::testing {
namespace {
using nlohmann::json;
using Clock = std::chrono::steady_clock;

/// An open /api/events response, read as it comes: each "data: ..." line as JSON.
class EventStream {
 public:
  EventStream(int port, const std::string& host, const std::string& token) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in dst{};
    dst.sin_family = AF_INET;
    dst.sin_port = htons(static_cast<uint16_t>(port));
    ::inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) return;
    capture::testing::send_all(fd_, request("GET", "/api/events", host, "X-Vdrig-Token: " + token + "\r\n"));
  }
  ~EventStream() {
    if (fd_ >= 0) ::close(fd_);
  }
  /// The next event satisfying `wanted` within `timeout_s`; null when none came.
  json next(const std::function<bool(const json&)>& wanted, double timeout_s = 10) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < deadline) {
      size_t at;
      while ((at = buffer_.find("data: ")) != std::string::npos) {
        const size_t end = buffer_.find('\n', at);
        if (end == std::string::npos) break;
        json j = json::parse(buffer_.substr(at + 6, end - at - 6), nullptr, false);
        buffer_.erase(0, end + 1);
        if (!j.is_discarded() && wanted(j)) return j;
      }
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      char buf[4096];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) return nullptr;
      buffer_.append(buf, static_cast<size_t>(n));
    }
    return nullptr;
  }

 private:
  int fd_ = -1;
  std::string buffer_;
};

auto event_is(const std::string& kind) {
  return [kind](const json& j) { return j.value("event", "") == kind; };
}

json post(Console& c, const std::string& path, const std::string& body, int* status = nullptr) {
  const HttpReply r =
      http(c.port(),
           request("POST", path, c.host(), "X-Vdrig-Token: " + c.token() + "\r\nOrigin: " + c.origin() + "\r\n", body));
  if (status) *status = r.status;
  return json::parse(r.body, nullptr, false);
}

TEST(WebApi, AStartIsValidatedByTheDaemonWithItsOwnWords) {
  vdrig::test::TempDir root("web_validate");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  int status = 0;
  const json refused =
      post(c, "/api/start", R"({"session":"v1","scheme":"latlong:0","bracket":"fixed:0.01"})", &status);
  EXPECT_EQ(status, 400);
  // The same request on the daemon's socket: the same code and text.
  std::string buffer;
  const int fd = capture::testing::connect_unix(root.path() / "run" / "vdrigd.sock");
  ASSERT_GE(fd, 0);
  const json direct = capture::testing::request(
      fd, buffer, {{"cmd", "start"}, {"session", "v1"}, {"scheme", "latlong:0"}, {"bracket", "fixed:0.01"}});
  ::close(fd);
  EXPECT_EQ(refused.value("code", "a"), direct.value("code", "b"));
  EXPECT_EQ(refused.value("error", "a"), direct.value("error", "b"));
  EXPECT_FALSE(refused.value("error", "").empty());
  // Only the form's fields, only as strings: a rig config or a command smuggled in is refused before the daemon.
  EXPECT_EQ(post(c, "/api/start", R"({"session":"v2","rig":{"stage":"x"}})", &status).value("error", ""),
            "unknown field rig");
  EXPECT_EQ(status, 400);
  EXPECT_EQ(post(c, "/api/start", R"({"session":"v2","cmd":"move"})", &status).value("code", ""), "bad_request");
  EXPECT_EQ(post(c, "/api/start", R"({"session":2})", &status).value("code", ""), "bad_request");
  EXPECT_EQ(post(c, "/api/start", "[1,2]", &status).value("code", ""), "bad_request");
  EXPECT_EQ(post(c, "/api/start", "{", &status).value("code", ""), "bad_request");
  EXPECT_FALSE(fs::exists(root.path() / "sessions" / "v2"));
}

TEST(WebApi, TheDaemonsEventsArriveAsServerSentEvents) {
  vdrig::test::TempDir root("web_events");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  EventStream events(c.port(), c.host(), c.token());
  EXPECT_TRUE(events.next([](const json& j) { return j.value("event", "") == "daemon" && j.value("connected", false); })
                  .is_object());
  EXPECT_EQ(events.next(event_is("status")).value("state", ""), "idle");

  int status = 0;
  const json started =
      post(c, "/api/start", R"({"session":"e1","scheme":"spiral:30:2@80","bracket":"fixed:0.01"})", &status);
  ASSERT_EQ(status, 200) << started.dump();
  EXPECT_EQ(started.value("views_total", 0), 30);
  const json progress = events.next(event_is("progress"));
  ASSERT_TRUE(progress.is_object()) << "no progress event";
  EXPECT_EQ(progress.value("session", ""), "e1");
  EXPECT_EQ(progress.value("views_total", 0), 30);

  post(c, "/api/pause", "{}", &status);
  ASSERT_EQ(status, 200);
  EXPECT_EQ(events.next(event_is("state")).value("state", ""), "paused");
  // A page opened now starts from the present: the replayed status says paused.
  EventStream late(c.port(), c.host(), c.token());
  EXPECT_EQ(late.next(event_is("state")).value("state", ""), "paused");

  post(c, "/api/resume", R"({"session":"e1"})", &status);
  ASSERT_EQ(status, 200);
  EXPECT_EQ(events.next(event_is("state")).value("state", ""), "running");
  const json done = events.next([](const json& j) { return j.value("state", "") == "completed"; }, 30);
  EXPECT_TRUE(done.is_object()) << "the session did not complete";
  // A page opened after the end is told the end last: no progress replayed after the final state.
  EventStream after(c.port(), c.host(), c.token());
  EXPECT_EQ(after.next(event_is("state")).value("state", ""), "completed");
  EXPECT_TRUE(after.next(event_is("progress"), 0.3).is_null()) << "a progress event replayed after the final state";
  const HttpReply list =
      http(c.port(), request("GET", "/api/sessions", c.host(), "X-Vdrig-Token: " + c.token() + "\r\n"));
  const json sessions = json::parse(list.body, nullptr, false);
  ASSERT_TRUE(sessions.contains("sessions")) << list.body;
  EXPECT_EQ(sessions["sessions"][0].value("views_done", 0), 30);
}

TEST(WebApi, ADaemonThatIsNotThereIs502AndSaidOnTheStream) {
  vdrig::test::TempDir root("web_nodaemon");
  ServerOptions options;
  options.runtime_dir = root.path() / "run";
  options.sessions_dir = root.path() / "sessions";
  auto server = Server::create(options);
  ASSERT_TRUE(server) << server.error().describe();
  std::thread serving([&] { (void)server.value()->run(); });
  const std::string host = "127.0.0.1:" + std::to_string(server.value()->port());
  const auto start = Clock::now();
  const HttpReply r = http(server.value()->port(),
                           request("GET", "/api/status", host, "X-Vdrig-Token: " + server.value()->token() + "\r\n"));
  EXPECT_EQ(r.status, 502) << r.body;
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 2.0);
  EventStream events(server.value()->port(), host, server.value()->token());
  const json down = events.next(event_is("daemon"));
  EXPECT_EQ(down.value("connected", true), false) << down.dump();
  server.value()->stop();
  serving.join();
}

}  // namespace
}  // namespace vdrig::web::testing

// capture::DaemonClient against a scripted peer on a Unix socket: what `vdrig session`, `vdrig serve` and the tests
// rely on (events skipped, a refusal read after a failed send, time limits, errors as values).
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <functional>
#include <thread>

#include "vdrig/capture/daemon_client.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::capture {
namespace {
using nlohmann::json;

/// A listening socket whose one accepted connection is handed to `script` on a thread.
class ScriptedPeer {
 public:
  ScriptedPeer(const std::filesystem::path& path, std::function<void(int)> script) : path_(path) {
    listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    EXPECT_EQ(::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    EXPECT_EQ(::listen(listen_fd_, 4), 0);
    thread_ = std::thread([this, script = std::move(script)] {
      const int fd = ::accept(listen_fd_, nullptr, nullptr);
      if (fd < 0) return;
      script(fd);
      ::close(fd);
    });
  }
  ~ScriptedPeer() {
    thread_.join();
    ::close(listen_fd_);
  }

 private:
  std::filesystem::path path_;
  int listen_fd_ = -1;
  std::thread thread_;
};

void write_text(int fd, const std::string& text) { ASSERT_TRUE(send_all(fd, text)); }

std::string read_request(int fd) {
  std::string buffer;
  auto line = read_line(fd, buffer, 5000);
  return line ? line.value() : "";
}

TEST(DaemonClient, ARequestSkipsEventsAndReturnsTheReplyOkOrNot) {
  test::TempDir dir("daemon_client_reply");
  const auto socket = dir.path() / "d.sock";
  std::string seen;
  {
    ScriptedPeer peer(socket, [&](int fd) {
      seen = read_request(fd);
      write_text(fd, "{\"event\":\"progress\",\"views_done\":1}\n{\"ok\":false,\"code\":\"busy\",\"error\":\"b\"}\n");
      seen += read_request(fd);
      write_text(fd, "{\"ok\":false,\"code\":\"not_found\",\"error\":\"no session x\"}\n");
    });
    DaemonClient c;
    ASSERT_TRUE(c.connect(socket));
    auto reply = c.request({{"cmd", "status"}}, 5000);
    ASSERT_TRUE(reply) << reply.error().describe();
    EXPECT_EQ(reply->value("code", ""), "busy");
    auto refused = c.call({{"cmd", "resume"}, {"session", "x"}}, 5000);
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error().code, ErrorCode::kNotFound) << refused.error().describe();
    EXPECT_EQ(refused.error().message, "no session x");
  }
  EXPECT_EQ(seen, "{\"cmd\":\"status\"}{\"cmd\":\"resume\",\"session\":\"x\"}");
}

TEST(DaemonClient, ARefusalWrittenBeforeTheRequestIsReadAsDisconnected) {
  test::TempDir dir("daemon_client_refusal");
  const auto socket = dir.path() / "d.sock";
  ScriptedPeer peer(socket, [](int fd) {
    write_text(fd, "{\"ok\":false,\"code\":\"permission_denied\",\"error\":\"uid 1234 is not allowed\"}\n");
    ::shutdown(fd, SHUT_RDWR);
  });
  DaemonClient c;
  ASSERT_TRUE(c.connect(socket));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the peer has closed before the request goes
  auto reply = c.call({{"cmd", "status"}}, 5000);
  ASSERT_FALSE(reply);
  EXPECT_EQ(reply.error().code, ErrorCode::kDisconnected);
  EXPECT_NE(reply.error().message.find("uid 1234 is not allowed"), std::string::npos) << reply.error().message;
}

TEST(DaemonClient, SilenceIsATimeoutAndGarbageIsCorrupt) {
  test::TempDir dir("daemon_client_timeout");
  const auto socket = dir.path() / "d.sock";
  ScriptedPeer peer(socket, [](int fd) {
    read_request(fd);
    std::this_thread::sleep_for(std::chrono::milliseconds(400));  // longer than the client waits
    write_text(fd, "not json\n");
    read_request(fd);
  });
  DaemonClient c;
  ASSERT_TRUE(c.connect(socket));
  const auto t0 = std::chrono::steady_clock::now();
  auto silent = c.request({{"cmd", "status"}}, 150);
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(silent);
  EXPECT_EQ(silent.error().code, ErrorCode::kTimeout);
  EXPECT_GE(waited_s, 0.14);
  EXPECT_LT(waited_s, 0.35);
  auto garbage = c.read_message(5000);
  ASSERT_FALSE(garbage);
  EXPECT_EQ(garbage.error().code, ErrorCode::kCorrupt);
  ASSERT_TRUE(c.send({{"cmd", "bye"}}));
}

TEST(DaemonClient, NoDaemonIsDisconnectedNamingTheSocket) {
  test::TempDir dir("daemon_client_absent");
  DaemonClient c;
  const Status s = c.connect(dir.path() / "absent.sock");
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDisconnected);
  EXPECT_NE(s.error().message.find("absent.sock"), std::string::npos);
  auto reply = c.request({{"cmd", "status"}}, 100);
  ASSERT_FALSE(reply);
  EXPECT_EQ(reply.error().code, ErrorCode::kDisconnected);
}

}  // namespace
}  // namespace vdrig::capture

// Helpers of the web console's tests: vdrigd on the small simulated rig and `vdrig serve`'s server, both in this
// process on threads of their own, and a raw HTTP/1.1 client (raw so that a test sends exactly the path, headers
// and source address it means, which an HTTP library would normalise).
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>

#include "../capture/sim_session.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/web/server.hpp"

namespace vdrig::web::testing {
namespace fs = std::filesystem;

/// vdrigd (the small simulated rig) and the web console on it, for the scope.
class Console {
 public:
  explicit Console(const fs::path& root, ServerOptions options = {})
      : daemon_(capture::testing::sim_daemon_config(root)) {
    daemon_started_ = daemon_.start();
    if (daemon_started_) daemon_thread_ = std::thread([this] { (void)daemon_.run(); });
    options.runtime_dir = root / "run";
    options.sessions_dir = root / "sessions";
    auto server = Server::create(options);
    if (!server) {
      server_started_ = server.status();
      return;
    }
    server_ = std::move(server.value());
    server_thread_ = std::thread([this] { (void)server_->run(); });
  }
  ~Console() {
    if (server_) server_->stop();
    if (server_thread_.joinable()) server_thread_.join();
    daemon_.request_stop();
    if (daemon_thread_.joinable()) daemon_thread_.join();
  }
  Console(const Console&) = delete;
  Console& operator=(const Console&) = delete;

  /// ok when both the daemon and the web server started.
  Status started() const { return daemon_started_ ? server_started_ : daemon_started_; }
  Server& server() { return *server_; }
  int port() const { return server_->port(); }
  const std::string& token() const { return server_->token(); }
  std::string host() const { return "127.0.0.1:" + std::to_string(port()); }
  std::string origin() const { return "http://" + host(); }

 private:
  capture::Daemon daemon_;
  Status daemon_started_, server_started_;
  std::thread daemon_thread_;
  std::unique_ptr<Server> server_;
  std::thread server_thread_;
};

struct HttpReply {
  int status = 0;    ///< 0: no reply (the connection failed or closed first)
  std::string head;  ///< status line and headers
  std::string body;  ///< as sent (chunked bodies are not decoded)
  std::string header(const std::string& name) const {
    const std::string key = "\r\n" + name + ": ";
    const auto at = head.find(key);
    if (at == std::string::npos) return "";
    const auto from = at + key.size();
    return head.substr(from, head.find("\r\n", from) - from);
  }
};

/// Sends `request` (a whole HTTP/1.1 request, "Connection: close" in it) to 127.0.0.1:`port` from the source
/// address `from` (any 127.x.y.z is this machine's: another client as the server sees it) and reads until the server
/// closes, or `timeout_ms` passes.
inline HttpReply http(int port, const std::string& request, const char* from = "127.0.0.1", int timeout_ms = 5000) {
  HttpReply reply;
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return reply;
  sockaddr_in src{};
  src.sin_family = AF_INET;
  ::inet_pton(AF_INET, from, &src.sin_addr);
  sockaddr_in dst{};
  dst.sin_family = AF_INET;
  dst.sin_port = htons(static_cast<uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&src), sizeof src) != 0 ||
      ::connect(fd, reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0 || !capture::testing::send_all(fd, request)) {
    ::close(fd);
    return reply;
  }
  std::string all;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    char buf[8192];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    all.append(buf, static_cast<size_t>(n));
  }
  ::close(fd);
  const auto end = all.find("\r\n\r\n");
  if (all.rfind("HTTP/1.1 ", 0) != 0 || end == std::string::npos) return reply;
  reply.status = std::atoi(all.c_str() + 9);
  reply.head = all.substr(0, end + 2);
  reply.body = all.substr(end + 4);
  return reply;
}

/// A request line and headers for `console`, with "Connection: close"; `extra` are more header lines, each ending
/// in \r\n.
inline std::string request(const std::string& method, const std::string& path, const std::string& host,
                           const std::string& extra = "", const std::string& body = "") {
  std::string r = method + " " + path + " HTTP/1.1\r\nHost: " + host + "\r\nConnection: close\r\n" + extra;
  if (method == "POST")
    r += "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) + "\r\n";
  return r + "\r\n" + body;
}

}  // namespace vdrig::web::testing

#include "vdrig/capture/daemon_client.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <utility>

#include "vdrig/capture/daemon.hpp"

namespace vdrig::capture {
using nlohmann::json;
using Clock = std::chrono::steady_clock;

Result<int> connect_unix(const std::filesystem::path& socket_path) {
  const std::string path = socket_path.string();
  sockaddr_un addr{};
  if (path.size() >= sizeof addr.sun_path) return make_error(ErrorCode::kInvalidArgument, "socket path too long");
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return make_error(ErrorCode::kIo, std::string("socket: ") + std::strerror(errno));
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd);
    return make_error(ErrorCode::kDisconnected, "cannot reach vdrigd at " + path + ": " + std::strerror(err));
  }
  return fd;
}

Status send_all(int fd, std::string_view bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return make_error(ErrorCode::kDisconnected, "send to vdrigd failed");
    done += static_cast<size_t>(n);
  }
  return Status::ok();
}

Result<std::string> read_line(int fd, std::string& buffer, int timeout_ms) {
  // One deadline for the whole line: a peer trickling bytes cannot stretch the wait.
  const auto deadline = Clock::now() + std::chrono::milliseconds(std::max(timeout_ms, 0));
  while (true) {
    const size_t pos = buffer.find('\n');
    if (pos != std::string::npos) {
      std::string line = buffer.substr(0, pos);
      buffer.erase(0, pos + 1);
      return line;
    }
    int wait_ms = -1;
    if (timeout_ms >= 0)
      wait_ms = static_cast<int>(
          std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count()));
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, wait_ms);
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) return make_error(ErrorCode::kTimeout, "vdrigd did not answer in time");
    char tmp[4096];
    const ssize_t n = ready < 0 ? -1 : ::recv(fd, tmp, sizeof tmp, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return make_error(ErrorCode::kDisconnected, "vdrigd closed the connection");
    buffer.append(tmp, static_cast<size_t>(n));
  }
}

Error daemon_reply_error(const json& reply) {
  const std::string code = reply.value("code", "");
  const std::string message = reply.value("error", std::string("request failed"));
  const bool too_many = code == "busy" && message.rfind("too many clients", 0) == 0;
  if (too_many || code == "permission_denied" || code == "idle_timeout")
    return make_error(ErrorCode::kDisconnected, "vdrigd refused the connection: " + message);
  // Every ErrorCode, in order, until wire_code's fallback "unknown" (past the last one).
  for (int c = 0; std::string(wire_code(static_cast<ErrorCode>(c))) != "unknown"; ++c)
    if (code == wire_code(static_cast<ErrorCode>(c))) return make_error(static_cast<ErrorCode>(c), message);
  return make_error(ErrorCode::kDevice, message);
}

DaemonClient::~DaemonClient() {
  if (fd_ >= 0) ::close(fd_);
}

DaemonClient::DaemonClient(DaemonClient&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), buffer_(std::move(other.buffer_)) {}

DaemonClient& DaemonClient::operator=(DaemonClient&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    buffer_ = std::move(other.buffer_);
  }
  return *this;
}

Status DaemonClient::connect(const std::filesystem::path& socket_path) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  buffer_.clear();
  auto fd = connect_unix(socket_path);
  if (!fd) return fd.status();
  fd_ = fd.value();
  return Status::ok();
}

Status DaemonClient::send(const json& message) {
  if (fd_ < 0) return make_error(ErrorCode::kDisconnected, "not connected to vdrigd");
  return send_all(fd_, message.dump() + "\n");
}

Result<std::string> DaemonClient::read_line(int timeout_ms) {
  if (fd_ < 0) return make_error(ErrorCode::kDisconnected, "not connected to vdrigd");
  return capture::read_line(fd_, buffer_, timeout_ms);
}

Result<json> DaemonClient::read_message(int timeout_ms) {
  auto line = read_line(timeout_ms);
  if (!line) return line.error();
  json j = json::parse(line.value(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) return make_error(ErrorCode::kCorrupt, "vdrigd sent invalid JSON");
  return j;
}

Result<json> DaemonClient::request(const json& req, int timeout_ms) {
  const Status sent = send(req);
  const auto deadline = Clock::now() + std::chrono::milliseconds(std::max(timeout_ms, 0));
  while (true) {
    int left_ms = -1;
    if (timeout_ms >= 0)
      left_ms = static_cast<int>(
          std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count()));
    auto m = read_message(left_ms);
    if (!m) return sent ? m.error() : sent.error();
    if (!m->contains("event")) return m;
    if (!sent) return sent.error();  // an event queued before the refusal: nothing of ours will follow
  }
}

Result<json> DaemonClient::call(const json& req, int timeout_ms) {
  auto reply = request(req, timeout_ms);
  if (reply && !reply->value("ok", false)) return daemon_reply_error(reply.value());
  return reply;
}

}  // namespace vdrig::capture

#include "daemon_server.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include "daemon_protocol.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string dump_line(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n"; }

}  // namespace

SocketServer::SocketServer(const DaemonConfig& config) : config_(config), logger_(log::get("vdrigd")) {}

SocketServer::~SocketServer() {
  for (auto& [fd, c] : clients_) ::close(fd);
  if (listen_fd_ >= 0) ::close(listen_fd_);
  for (int fd : wake_pipe_)
    if (fd >= 0) ::close(fd);
}

fs::path SocketServer::socket_path() const { return config_.runtime_dir / "vdrigd.sock"; }

void SocketServer::wake() {
  if (wake_pipe_[1] < 0) return;
  const char b = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_pipe_[1], &b, 1);
}

Status SocketServer::make_runtime_dir() {
  const std::string dir = config_.runtime_dir.string();
  // Create only what the daemon owns: a folder made here gets 0770; an existing one (a shared 1777 /tmp-like
  // folder, a systemd RuntimeDirectory) keeps the mode its owner gave it.
  struct stat dir_st {};
  if (::stat(dir.c_str(), &dir_st) != 0) {
    if (errno != ENOENT) return make_error(ErrorCode::kIo, "cannot look at " + dir + ": " + std::strerror(errno));
    std::error_code ec;
    if (config_.runtime_dir.has_parent_path()) fs::create_directories(config_.runtime_dir.parent_path(), ec);
    if (::mkdir(dir.c_str(), 0770) != 0 && errno != EEXIST)
      return make_error(ErrorCode::kIo, "cannot create " + dir + ": " + std::strerror(errno));
    ::chmod(dir.c_str(), 0770);  // exactly 0770 whatever the umask: it is ours
  } else if (!S_ISDIR(dir_st.st_mode)) {
    return make_error(ErrorCode::kInvalidArgument, "runtime dir " + dir + " is not a folder");
  }
  return Status::ok();
}

Status SocketServer::open() {
  VDRIG_TRY(make_runtime_dir());
  if (::pipe2(wake_pipe_, O_NONBLOCK | O_CLOEXEC) != 0)
    return make_error(ErrorCode::kIo, std::string("pipe: ") + std::strerror(errno));

  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string path = socket_path().string();  // DaemonConfig::is_valid checked that it fits
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode))
      return make_error(ErrorCode::kInvalidArgument,
                        path + " exists and is not a socket; remove it or choose another --runtime-dir");
    // A live daemon answers a connect; a stale socket (a crash) refuses it and is replaced. Anything else (no
    // permission to connect) is not ours to remove.
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (probe < 0) return make_error(ErrorCode::kIo, std::string("socket: ") + std::strerror(errno));
    const int rc = ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
    const int err = errno;
    ::close(probe);
    if (rc == 0) return make_error(ErrorCode::kInvalidArgument, "another daemon is serving " + path);
    if (err != ECONNREFUSED)
      return make_error(ErrorCode::kInvalidArgument,
                        "cannot tell whether " + path + " is stale: " + std::strerror(err));
    ::unlink(path.c_str());
  } else if (errno != ENOENT) {
    return make_error(ErrorCode::kIo, "cannot look at " + path + ": " + std::strerror(errno));
  }
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listen_fd_ < 0) return make_error(ErrorCode::kIo, std::string("socket: ") + std::strerror(errno));
  // Bind with a restrictive umask so the socket is never briefly world-accessible, then set exactly 0660.
  const mode_t old_mask = ::umask(0117);
  const int rc = ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  ::umask(old_mask);
  if (rc != 0) return make_error(ErrorCode::kIo, "bind " + path + ": " + std::strerror(errno));
  bound_ = true;
  ::chmod(path.c_str(), 0660);
  // A deep backlog: a burst of clients (200 asking `status` at once) waits in the kernel's queue for accept() and
  // gets its answer or a "too many clients" reply, instead of timing out on connect.
  if (::listen(listen_fd_, SOMAXCONN) != 0)
    return make_error(ErrorCode::kIo, std::string("listen: ") + std::strerror(errno));
  logger_->info("listening on {} (uid {} allowed)", path, config_.allowed_uid);
  return Status::ok();
}

void SocketServer::send(Connection& c, const json& j) {
  if (c.closing && c.fd < 0) return;
  c.out += dump_line(j);
  if (c.out.size() > config_.max_output_bytes) {
    logger_->warn("client {} is not reading ({} bytes queued): dropped", c.fd, c.out.size());
    c.out.clear();
    c.closing = true;
  }
}

void SocketServer::push(const json& event) {
  for (auto& [fd, c] : clients_)
    if (c.subscribed && !c.closing) send(c, event);
}

void SocketServer::send_deferred(const json& reply) {
  for (auto& [fd, c] : clients_)
    if (c.awaiting_reply) {
      c.awaiting_reply = false;
      if (!c.closing) send(c, reply);
      return;
    }
}

void SocketServer::accept_clients() {
  while (true) {
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;  // EAGAIN or a transient error: poll again
    ucred cred{};
    socklen_t len = sizeof cred;
    const bool known = ::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) == 0;
    const bool allowed =
        known && (cred.uid == config_.allowed_uid || (config_.allowed_gid && cred.gid == *config_.allowed_gid));
    int of_uid = 0;
    for (const auto& [other_fd, other] : clients_) of_uid += known && other.uid == cred.uid ? 1 : 0;
    const bool room = static_cast<int>(clients_.size()) < config_.max_clients;
    const bool uid_room = of_uid < config_.max_clients_per_uid;
    if (!allowed || !room || !uid_room) {
      const json refusal = !allowed ? error_reply({wire::kPermissionDenied, "peer not allowed"})
                           : !room
                               ? error_reply({wire::kBusy, "too many clients (" + std::to_string(config_.max_clients) +
                                                               " connected); try again later"})
                               : error_reply({wire::kBusy, "too many clients of uid " + std::to_string(cred.uid) +
                                                               " (" + std::to_string(config_.max_clients_per_uid) +
                                                               " connected); close some or try again later"});
      const std::string reply = dump_line(refusal);
      [[maybe_unused]] const ssize_t n = ::send(fd, reply.data(), reply.size(), MSG_NOSIGNAL);
      // One line per refusal, but at most one a second: a crowd of 200 clients must not flood the log.
      const auto now = std::chrono::steady_clock::now();
      if (now - last_refusal_log_ >= std::chrono::seconds(1)) {
        logger_->warn(
            "refused connection from uid {} gid {}: {}{}", known ? static_cast<long>(cred.uid) : -1L,
            known ? static_cast<long>(cred.gid) : -1L, refusal.value("error", ""),
            refusals_unlogged_ ? fmt::format(" ({} more refused since the last such line)", refusals_unlogged_) : "");
        last_refusal_log_ = now;
        refusals_unlogged_ = 0;
      } else {
        ++refusals_unlogged_;
      }
      ::close(fd);
      continue;
    }
    Connection& c = clients_[fd];
    c.fd = fd;
    c.uid = cred.uid;
    c.last_request = std::chrono::steady_clock::now();
  }
}

bool SocketServer::has_pending_line(const Connection& c) {
  return !c.closing && !c.awaiting_reply && c.in.find('\n') != std::string::npos;
}

bool SocketServer::read_client(Connection& c) {
  char buf[16384];
  const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
  if (n == 0) {
    c.eof = true;
    return true;
  }
  if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
  if (c.closing) return true;  // discard input after a fatal request
  c.in.append(buf, static_cast<size_t>(n));
  c.last_request = std::chrono::steady_clock::now();
  return true;  // an unfinished line that is already too long is refused by answer_client()
}

void SocketServer::answer_client(Connection& c, const LineHandler& on_line) {
  size_t start = 0;
  for (int answered = 0; answered < kRequestsPerRound && !c.closing && !c.awaiting_reply; ++answered) {
    const size_t pos = c.in.find('\n', start);
    if (pos == std::string::npos) break;
    const std::string line = c.in.substr(start, pos - start);
    start = pos + 1;
    if (line.size() > config_.max_line_bytes) {
      too_long(c);
      break;
    }
    auto reply = on_line(line, c.subscribed);
    if (!reply) {
      c.awaiting_reply = true;  // later lines wait for this reply, in order
      break;
    }
    send(c, *reply);
  }
  if (c.closing) return;
  c.in.erase(0, start);
  if (c.in.find('\n') == std::string::npos && c.in.size() > config_.max_line_bytes) too_long(c);
}

void SocketServer::too_long(Connection& c) {
  send(c, error_reply(
              {wire::kTooLong, "request longer than " + std::to_string(config_.max_line_bytes) + " bytes; closing"}));
  c.in.clear();
  c.closing = true;
}

bool SocketServer::flush_client(Connection& c) {
  while (!c.out.empty()) {
    const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL);
    if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
    c.out.erase(0, static_cast<size_t>(n));
  }
  return true;
}

Status SocketServer::serve(const std::atomic<bool>& stop, const LineHandler& on_line,
                           const std::function<void()>& after_io) {
  while (!stop.load()) {
    std::vector<pollfd> fds;
    fds.push_back({listen_fd_, POLLIN, 0});
    fds.push_back({wake_pipe_[0], POLLIN, 0});
    bool work_pending = false;
    for (auto& [fd, c] : clients_) {
      // A client with unanswered lines is not read from until they are answered (round-robin, bounded buffers).
      const bool pending = has_pending_line(c);
      work_pending = work_pending || pending;
      short ev = c.closing || c.eof || pending || c.awaiting_reply ? 0 : POLLIN;
      if (!c.out.empty()) ev |= POLLOUT;
      fds.push_back({fd, ev, 0});
    }
    const int n = ::poll(fds.data(), fds.size(), work_pending ? 0 : close_idle(1000));
    if (n < 0) {
      if (errno == EINTR) continue;
      return make_error(ErrorCode::kIo, std::string("poll: ") + std::strerror(errno));
    }
    if (fds[1].revents & POLLIN) {
      char buf[256];
      while (::read(wake_pipe_[0], buf, sizeof buf) > 0) {
      }
    }
    for (size_t k = 2; k < fds.size(); ++k) {
      auto it = clients_.find(fds[k].fd);
      if (it == clients_.end()) continue;
      Connection& c = it->second;
      bool alive = true;
      if ((fds[k].revents & (POLLIN | POLLHUP | POLLERR)) && !c.eof && !has_pending_line(c)) alive = read_client(c);
      if (alive && (fds[k].revents & POLLERR)) alive = false;
      if (!alive) {
        ::close(c.fd);
        clients_.erase(it);
      }
    }
    // One turn each: at most kRequestsPerRound answers per client.
    for (auto& [fd, c] : clients_) answer_client(c, on_line);
    if (fds[0].revents & POLLIN) accept_clients();
    after_io();
    for (auto it = clients_.begin(); it != clients_.end();) {
      Connection& c = it->second;
      const bool ok = flush_client(c);
      const bool done = c.out.empty() && !c.awaiting_reply && (c.closing || (c.eof && !has_pending_line(c)));
      if (!ok || done) {
        ::close(c.fd);
        it = clients_.erase(it);
      } else {
        ++it;
      }
    }
  }
  return Status::ok();
}

int SocketServer::close_idle(int cap_ms) {
  using namespace std::chrono;
  const auto now = steady_clock::now();
  const auto timeout = duration_cast<steady_clock::duration>(duration<double>(config_.idle_timeout_s));
  auto next = milliseconds(cap_ms);
  for (auto& [fd, c] : clients_) {
    // Exempt: watchers, and connections with a request in hand or output still to send.
    if (c.subscribed || c.closing || c.awaiting_reply || !c.in.empty() || !c.out.empty()) continue;
    const auto idle = now - c.last_request;
    if (idle >= timeout) {
      logger_->info("client {} (uid {}) idle for {:.0f} s: closed", fd, static_cast<long>(c.uid),
                    duration<double>(idle).count());
      send(c, error_reply({wire::kIdleTimeout,
                           "no request for " + fmt::format("{:g}", config_.idle_timeout_s) + " s; closing"}));
      c.closing = true;
    } else {
      next = std::min(next, duration_cast<milliseconds>(timeout - idle) + milliseconds(1));
    }
  }
  return static_cast<int>(next.count());
}

void SocketServer::close() {
  for (auto& [fd, c] : clients_) {
    (void)flush_client(c);
    ::close(fd);
  }
  clients_.clear();
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
  if (bound_) {  // only the socket this server bound
    ::unlink(socket_path().c_str());
    bound_ = false;
  }
}

}  // namespace vdrig::capture

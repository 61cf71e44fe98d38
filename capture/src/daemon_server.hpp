// vdrigd's socket server: the Unix socket (0660, in a folder created 0770 when missing), peer credentials
// (SO_PEERCRED), line framing and per-connection buffers, in one poll() loop. It knows nothing of commands: each
// complete line goes to a callback whose reply it queues, and it pushes events to the connections that asked for them.
// Clients are served round-robin: at most kRequestsPerRound lines of one client are answered per loop round, and a
// client with unanswered lines is not read from (its kernel buffer fills and its writes block), so one client
// pipelining thousands of requests delays another by a few requests at most.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "vdrig/capture/daemon.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {

/// One client connection.
struct Connection {
  int fd = -1;
  std::string in;               // bytes received, not yet a complete line
  std::string out;              // bytes queued for sending
  bool subscribed = false;      // wants pushed events (set by the protocol's `subscribe`)
  bool closing = false;         // input is ignored; close once `out` is flushed
  bool eof = false;             // the peer shut down its writing side: answer what is in `in`, then close
  bool awaiting_reply = false;  // a request's reply comes later (send_deferred); later lines wait for it
  uid_t uid = 0;                // the peer's (SO_PEERCRED), for the per-uid limit
  std::chrono::steady_clock::time_point last_request{};  // accepted, or the last byte of a request received
};

/// Answers one request line (its '\n' and any '\r' left on): the reply object, or nullopt when the reply comes
/// later through send_deferred() (the connection's further lines wait; other clients are served). May set
/// `subscribed`.
using LineHandler = std::function<std::optional<nlohmann::json>(const std::string& line, bool& subscribed)>;

class SocketServer {
 public:
  /// `config` (runtime_dir, allowed peers, limits) must outlive the server.
  explicit SocketServer(const DaemonConfig& config);
  ~SocketServer();
  SocketServer(const SocketServer&) = delete;
  SocketServer& operator=(const SocketServer&) = delete;

  std::filesystem::path socket_path() const;

  /// Lines of one client answered per loop round before the others get their turn.
  static constexpr int kRequestsPerRound = 4;

  /// Creates the runtime dir 0770 when missing; an existing one is used as it is (its mode is its owner's).
  Status make_runtime_dir();
  /// make_runtime_dir(), then binds the socket (0660). A stale socket at the path (connect refused) is replaced; a
  /// live daemon on it, or anything that is not a socket, is kInvalidArgument and left alone.
  Status open();
  /// Serves until `stop` is set: answers each request line with `on_line`, then calls `after_io` (for pushing
  /// events), then writes what it can. Returns only a fatal error (poll failure), else ok.
  Status serve(const std::atomic<bool>& stop, const LineHandler& on_line, const std::function<void()>& after_io);
  /// Queues `event` on every subscribed connection.
  void push(const nlohmann::json& event);
  /// Queues the deferred reply on the connection waiting for it (dropped when that client has gone).
  void send_deferred(const nlohmann::json& reply);
  /// Writes what can be written without blocking, closes every connection and the socket, and removes it.
  void close();
  /// Async-signal-safe: makes a waiting serve() look at its state again.
  void wake();

 private:
  void accept_clients();
  /// Reads what is there (one recv); false when the connection failed.
  bool read_client(Connection& c);
  /// Answers up to kRequestsPerRound complete lines of `c`.
  void answer_client(Connection& c, const LineHandler& on_line);
  /// Whether `c` has a complete request line not yet answered.
  static bool has_pending_line(const Connection& c);
  void too_long(Connection& c);
  /// Tells connections idle for config_.idle_timeout_s so and closes them; returns the milliseconds until the next
  /// one may time out (at most `cap_ms`).
  int close_idle(int cap_ms);
  void send(Connection& c, const nlohmann::json& j);
  /// Writes queued output; false on a write error.
  static bool flush_client(Connection& c);

  const DaemonConfig& config_;
  int listen_fd_ = -1;
  bool bound_ = false;  // socket_path() is this server's socket (close() removes it)
  std::chrono::steady_clock::time_point last_refusal_log_{};  // refusals are logged at most once a second
  int refusals_unlogged_ = 0;
  int wake_pipe_[2] = {-1, -1};
  std::map<int, Connection> clients_;
  std::shared_ptr<spdlog::logger> logger_;
};

}  // namespace vdrig::capture

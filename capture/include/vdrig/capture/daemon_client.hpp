// The one client of vdrigd's socket (docs/protocol.md): newline-framed JSON over a Unix stream socket. Used by
// `vdrig session`, `vdrig serve` and the tests; errors are values (kDisconnected, kTimeout, kCorrupt).
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "vdrig/core/result.hpp"

namespace vdrig::capture {

/// A connected socket (SOCK_CLOEXEC) to `socket_path`; kDisconnected saying why when it cannot be reached.
Result<int> connect_unix(const std::filesystem::path& socket_path);
/// Writes every byte (MSG_NOSIGNAL: a closed peer is kDisconnected, not SIGPIPE).
Status send_all(int fd, std::string_view bytes);
/// The next line from `fd`, `buffer` holding what was read past it. kTimeout when none came within `timeout_ms`
/// (-1: wait for ever), kDisconnected when the peer closed first.
Result<std::string> read_line(int fd, std::string& buffer, int timeout_ms = -1);

/// A daemon's error reply as an Error: a refused or dropped connection (docs/protocol.md, "Connections") as
/// kDisconnected saying so, a failure the daemon reports by ErrorCode (wire_code) as that ErrorCode, the protocol's
/// own refusals (busy, bad_request, ...) as kDevice with the daemon's text.
Error daemon_reply_error(const nlohmann::json& reply);

/// One connection to vdrigd, closed with the object.
class DaemonClient {
 public:
  DaemonClient() = default;
  ~DaemonClient();
  DaemonClient(DaemonClient&& other) noexcept;
  DaemonClient& operator=(DaemonClient&& other) noexcept;
  DaemonClient(const DaemonClient&) = delete;
  DaemonClient& operator=(const DaemonClient&) = delete;

  Status connect(const std::filesystem::path& socket_path);
  bool connected() const { return fd_ >= 0; }
  int fd() const { return fd_; }

  Status send(const nlohmann::json& message);
  Result<std::string> read_line(int timeout_ms = -1);
  /// The next message, reply or event; kCorrupt for a line that is not a JSON object.
  Result<nlohmann::json> read_message(int timeout_ms = -1);
  /// Sends `request` and returns the daemon's reply line, ok or not (events that arrive first are skipped). A daemon
  /// refusing this peer writes the reason and closes, maybe before the send: a failed send still reads the reason.
  Result<nlohmann::json> request(const nlohmann::json& request, int timeout_ms = -1);
  /// As request(), but a reply that is not ok is daemon_reply_error(reply).
  Result<nlohmann::json> call(const nlohmann::json& request, int timeout_ms = -1);

 private:
  int fd_ = -1;
  std::string buffer_;
};

}  // namespace vdrig::capture

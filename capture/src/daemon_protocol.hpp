// vdrigd's protocol (docs/protocol.md): checks a request line (UTF-8, a JSON object, "id", "cmd"), looks the
// command up in a table that names each command's fields and their types, validates those, and runs the handler.
// Failures are values (Reply), never exceptions.
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "vdrig/capture/daemon.hpp"

namespace vdrig::capture {

class SessionRunner;

/// The protocol's own error codes; failures reported as an Error carry wire_code(error.code) instead.
namespace wire {
inline constexpr const char* kBadRequest = "bad_request";              // not UTF-8/JSON/an object, bad fields
inline constexpr const char* kUnknownCommand = "unknown_command";      // "cmd" names no command
inline constexpr const char* kInvalidState = "invalid_state";          // pause/abort with nothing to stop
inline constexpr const char* kBusy = "busy";                           // a session runs, or too many clients
inline constexpr const char* kTooLong = "too_long";                    // a line above max_line_bytes (then closed)
inline constexpr const char* kPermissionDenied = "permission_denied";  // peer credentials refused (then closed)
inline constexpr const char* kIdleTimeout = "idle_timeout";            // no request for idle_timeout_s (then closed)
}  // namespace wire

/// A failed request as sent back: {"ok": false, "code": code, "error": message}.
struct RequestError {
  std::string code;
  std::string message;
};

/// The reply to a failed request; `id` (when not null) is echoed.
nlohmann::json error_reply(const RequestError& error, const nlohmann::json& id = nullptr);

/// What a command handler returns: the reply's fields, or why the request failed.
class [[nodiscard]] Reply {
 public:
  Reply(nlohmann::json fields) : v_(std::move(fields)) {}  // NOLINT: implicit by design
  Reply(RequestError error) : v_(std::move(error)) {}      // NOLINT: implicit by design
  /// A rig, disk or session failure: its code on the wire is wire_code(error.code).
  Reply(const Error& error) : v_(RequestError{wire_code(error.code), error.message}) {}  // NOLINT: implicit

  /// The whole reply line's object ("ok", the fields or "code"/"error", and `id` when not null).
  nlohmann::json to_json(const nlohmann::json& id) &&;

 private:
  std::variant<nlohmann::json, RequestError> v_;
};

/// Strict UTF-8 (no overlong forms, no surrogates, nothing above U+10FFFF).
bool valid_utf8(std::string_view s);

class Protocol {
 public:
  /// `config` and `runner` must outlive the protocol.
  Protocol(const DaemonConfig& config, SessionRunner& runner);

  /// Answers one request line (without its '\n'; a trailing '\r' is ignored): the whole reply object, or nullopt
  /// for a `home`/`move` that was started and is answered by take_deferred_reply() when it ends (the connection
  /// waits for it; others are served meanwhile). `subscribe` sets `subscribed`. Never throws.
  std::optional<nlohmann::json> answer(const std::string& line, bool& subscribed);
  /// The reply to the deferred `home`/`move` once the stage has finished; nullopt until then.
  std::optional<nlohmann::json> take_deferred_reply();

 private:
  enum class FieldType { kString, kNumber, kObject };
  struct Field {
    const char* name;
    FieldType type;
    bool required;
  };
  using Handler = Reply (Protocol::*)(const nlohmann::json& request, bool& subscribed);
  struct Command {
    std::vector<Field> fields;  // besides "cmd" and "id"; any other field is a bad_request
    Handler handler;
  };
  static const std::map<std::string, Command, std::less<>>& commands();
  Reply answer_request(std::string_view line, nlohmann::json& id, bool& subscribed);

  Reply status(const nlohmann::json& request, bool& subscribed);
  Reply subscribe(const nlohmann::json& request, bool& subscribed);
  Reply start(const nlohmann::json& request, bool& subscribed);
  Reply pause(const nlohmann::json& request, bool& subscribed);
  Reply abort(const nlohmann::json& request, bool& subscribed);
  Reply resume(const nlohmann::json& request, bool& subscribed);
  Reply home(const nlohmann::json& request, bool& subscribed);
  Reply move(const nlohmann::json& request, bool& subscribed);
  Reply list_sessions(const nlohmann::json& request, bool& subscribed);
  Reply stop(const nlohmann::json& request, bool& subscribed);

  const DaemonConfig& config_;
  SessionRunner& runner_;
  bool deferred_ = false;       // set by home/move when the reply comes later
  nlohmann::json deferred_id_;  // the deferred request's "id"
};

}  // namespace vdrig::capture

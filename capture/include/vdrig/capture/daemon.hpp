// vdrigd's engine: runs capture sessions on one rig in a worker thread, controlled over a Unix domain socket with
// line-delimited JSON (docs/protocol.md). apps/vdrigd is a shell around it; tests run it in-process.
//
// Threads: run() owns every socket and answers every request on the calling thread; one worker thread runs the
// session in hand. Planning a new session and `home`/`move` block the loop until done. No exception leaves run().
#pragma once

#include <sys/types.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/capture/capture.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::capture {

struct DaemonConfig {
  std::filesystem::path runtime_dir;           // the socket is runtime_dir/vdrigd.sock (0660); created 0770 if missing
  std::filesystem::path sessions_dir;          // sessions live in sessions_dir/NAME
  uid_t allowed_uid = static_cast<uid_t>(-1);  // -1: the daemon's own effective uid
  std::optional<gid_t> allowed_gid;            // peers with this primary gid are accepted too
  nlohmann::json rig_config;                   // rig used when `start` names none ("scene" overrides sim.scene)
  /// Builds a rig from a config (e.g. a registry with the sim and hardware backends). Required.
  std::function<Result<rig::Rig>(const nlohmann::json& rig_config)> make_rig;
  /// Optional: fills in what the rig config implies about the surface (size) before the manifest is written.
  std::function<void(Manifest& manifest)> describe_surface;
  CaptureOptions capture;                  // gain, disk reserve, retry policy (bracket comes from `start`)
  std::size_t max_line_bytes = 64 * 1024;  // longer requests: error reply, connection closed
  std::size_t max_output_bytes = 8 << 20;  // a client this far behind (not reading its events) is dropped
  int max_clients = 64;                    // connections in all; more are refused with "busy" ("too many clients")
  int max_clients_per_uid = 16;  // connections of one peer uid, so that one user's idle sockets cannot lock out others
  // A connection with no request for this long is told so ("idle_timeout") and closed; one that subscribed to events
  // is exempt (it is a watcher, and the per-uid limit bounds those).
  double idle_timeout_s = 60.0;

  bool is_valid(std::string* why) const;
};

/// $XDG_RUNTIME_DIR/vdrig, or /run/vdrig when unset.
std::filesystem::path default_runtime_dir();

/// Session names: 1..64 characters of [A-Za-z0-9._-], not starting with '.' (no traversal, no hidden files).
bool valid_session_name(const std::string& name, std::string* why = nullptr);

/// The "code" of an error reply (and of status' "error_code") for a failure reported as an Error: one distinct
/// snake_case name per ErrorCode ("invalid_argument", "no_space", "not_found", ...).
const char* wire_code(ErrorCode code);
/// The codes the protocol itself uses besides wire_code()'s ("bad_request", "busy", "too_long", ...).
/// docs/protocol.md lists exactly these and wire_code() of every ErrorCode.
std::vector<std::string> protocol_error_codes();

class Daemon {
 public:
  explicit Daemon(DaemonConfig config);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Validates the config, creates the runtime dir and binds the socket (a stale socket file is replaced; a live
  /// daemon on it is kInvalidArgument).
  Status start();
  /// Serves until request_stop(): then stops the session after the frame in hand, parks the axes, closes and
  /// removes the socket. Returns the first fatal loop error (poll failure), else ok.
  Status run();
  /// Async-signal-safe: asks run() to shut down (SIGTERM handler).
  void request_stop();

  std::filesystem::path socket_path() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace vdrig::capture

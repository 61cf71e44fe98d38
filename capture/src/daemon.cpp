// The daemon assembled from its three parts: the socket server (daemon_server.*), the protocol (daemon_protocol.*)
// and the session runner (session_runner.*).
#include "vdrig/capture/daemon.hpp"

#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <exception>

#include "daemon_protocol.hpp"
#include "daemon_server.hpp"
#include "session_runner.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;

fs::path default_runtime_dir() {
  const char* xdg = std::getenv("XDG_RUNTIME_DIR");
  if (xdg && *xdg) return fs::path(xdg) / "vdrig";
  return "/run/vdrig";
}

bool valid_session_name(const std::string& name, std::string* why) {
  auto fail = [&](const char* w) {
    if (why) *why = w;
    return false;
  };
  if (name.empty() || name.size() > 64) return fail("session name must be 1..64 characters");
  if (name[0] == '.') return fail("session name must not start with '.'");
  for (char c : name) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok) return fail("session name may hold only A-Z a-z 0-9 . _ -");
  }
  return true;
}

bool DaemonConfig::is_valid(std::string* why) const {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (runtime_dir.empty()) return fail("runtime_dir is empty");
  if (sessions_dir.empty()) return fail("sessions_dir is empty");
  if ((runtime_dir / "vdrigd.sock").string().size() >= sizeof(sockaddr_un{}.sun_path))
    return fail("socket path too long for a Unix socket: " + (runtime_dir / "vdrigd.sock").string());
  if (!make_rig) return fail("no rig factory");
  if (max_line_bytes < 64) return fail("max_line_bytes too small");
  if (max_clients < 1) return fail("max_clients must be >= 1");
  if (max_clients_per_uid < 1 || max_clients_per_uid > max_clients)
    return fail("max_clients_per_uid must be 1..max_clients (" + std::to_string(max_clients) + ")");
  if (!(idle_timeout_s > 0.0)) return fail("idle_timeout_s must be > 0");
  return true;
}

struct Daemon::Impl {
  explicit Impl(DaemonConfig c)
      : config(std::move(c)), server(config), runner(config, [this] { server.wake(); }), protocol(config, runner) {}

  DaemonConfig config;
  std::atomic<bool> stop_flag{false};
  SocketServer server;   // before the runner: the worker wakes the server's loop until the runner joins it
  SessionRunner runner;  // owns the rig and the worker thread
  Protocol protocol;
};

Daemon::Daemon(DaemonConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}
Daemon::~Daemon() = default;

Status Daemon::start() {
  DaemonConfig& config = impl_->config;
  std::string why;
  if (!config.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "daemon config: " + why);
  if (config.allowed_uid == static_cast<uid_t>(-1)) config.allowed_uid = ::geteuid();
  std::error_code ec;
  fs::create_directories(config.sessions_dir, ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + config.sessions_dir.string() + ": " + ec.message());
  // A rig config that does not build (unknown backend, bad settings) or a rig another process drives is refused
  // before listening, not at the first request. (Its lock lives in the runtime dir, made first.)
  VDRIG_TRY(impl_->server.make_runtime_dir());
  if (const Status rig = impl_->runner.prepare(); !rig)
    return make_error(rig.error().code, "rig config: " + rig.error().message);
  return impl_->server.open();
}

Status Daemon::run() {
  Impl& d = *impl_;
  Status loop = Status::ok();
  // The parts return failures as values; this catch only keeps the contract that no exception leaves run()
  // (allocation failure in the loop itself).
  try {
    loop = d.server.serve(
        d.stop_flag, [&](const std::string& line, bool& subscribed) { return d.protocol.answer(line, subscribed); },
        [&] {
          for (const auto& event : d.runner.take_events()) d.server.push(event);
          if (auto reply = d.protocol.take_deferred_reply()) d.server.send_deferred(*reply);
        });
    log::get("vdrigd")->info("shutting down");
    d.runner.shutdown();
    for (const auto& event : d.runner.take_events()) d.server.push(event);
    d.server.close();
  } catch (const std::exception& e) {
    return make_error(ErrorCode::kInternal, std::string("daemon loop: ") + e.what());
  }
  return loop;
}

void Daemon::request_stop() {
  impl_->stop_flag.store(true);
  impl_->server.wake();
}

fs::path Daemon::socket_path() const { return impl_->server.socket_path(); }

}  // namespace vdrig::capture

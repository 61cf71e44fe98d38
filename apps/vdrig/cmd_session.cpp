// vdrig session start|status|pause|resume|abort|list: a client of vdrigd (docs/protocol.md); vdrig session check:
// fsck for a session folder (capture/session_check.hpp), run locally.
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/capture/session_check.hpp"

namespace vdrig::app {
namespace {
using nlohmann::json;

struct SessionArgs {
  std::string runtime_dir = capture::default_runtime_dir().string();
  std::string name;
  std::string scheme = capture::kDefaultScheme;
  std::string bracket = "auto";
  std::string scene;
  bool follow = false;
};

class Client {
 public:
  ~Client() {
    if (fd_ >= 0) ::close(fd_);
  }
  Status connect(const std::string& runtime_dir) {
    const std::string path = runtime_dir + "/vdrigd.sock";
    sockaddr_un addr{};
    if (path.size() >= sizeof addr.sun_path) return make_error(ErrorCode::kInvalidArgument, "socket path too long");
    addr.sun_family = AF_UNIX;
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0 || ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      return make_error(ErrorCode::kDisconnected, "cannot reach vdrigd at " + path + ": " + std::strerror(errno));
    return Status::ok();
  }
  Result<json> read_message() {
    while (true) {
      const size_t pos = buf_.find('\n');
      if (pos != std::string::npos) {
        json j = json::parse(buf_.substr(0, pos), nullptr, false);
        buf_.erase(0, pos + 1);
        if (j.is_discarded()) return make_error(ErrorCode::kCorrupt, "daemon sent invalid JSON");
        return j;
      }
      char tmp[4096];
      const ssize_t n = ::recv(fd_, tmp, sizeof tmp, 0);
      if (n <= 0) return make_error(ErrorCode::kDisconnected, "daemon closed the connection");
      buf_.append(tmp, static_cast<size_t>(n));
    }
  }
  /// Sends a request and returns its reply (events that arrive first are skipped).
  Result<json> request(const json& req) {
    const std::string line = req.dump() + "\n";
    if (::send(fd_, line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size())) {
      // A daemon refusing this peer (its uid, too many clients) writes the reason and closes at once, possibly
      // before this send: the reason is still there to read.
      auto m = read_message();
      if (m && !m->contains("event") && !m->value("ok", false)) return reply_error(m.value());
      return make_error(ErrorCode::kDisconnected, "send to daemon failed");
    }
    while (true) {
      auto m = read_message();
      if (!m) return m;
      if (m->contains("event")) continue;
      if (!m->value("ok", false)) return reply_error(m.value());
      return m;
    }
  }

 private:
  /// The daemon's error reply as an Error: a refused or dropped connection (docs/protocol.md, "Connections") as
  /// kDisconnected saying so, a failure the daemon reports by ErrorCode (capture::wire_code) as that ErrorCode, the
  /// protocol's own refusals of a request (busy, bad_request, ...) as before.
  static Error reply_error(const json& reply) {
    const std::string code = reply.value("code", "");
    const std::string message = reply.value("error", std::string("request failed"));
    const bool too_many = code == "busy" && message.rfind("too many clients", 0) == 0;
    if (too_many || code == "permission_denied" || code == "idle_timeout")
      return make_error(ErrorCode::kDisconnected, "vdrigd refused the connection: " + message);
    // Every ErrorCode, in order, until wire_code's fallback "unknown" (past the last one).
    for (int c = 0; std::string(capture::wire_code(static_cast<ErrorCode>(c))) != "unknown"; ++c)
      if (code == capture::wire_code(static_cast<ErrorCode>(c))) return make_error(static_cast<ErrorCode>(c), message);
    return make_error(ErrorCode::kDevice, message);
  }

  int fd_ = -1;
  std::string buf_;
};

void print_status(const json& s) {
  std::printf("%s", s.value("state", "?").c_str());
  if (s.contains("session"))
    std::printf("  %s  views %d/%d", s["session"].get<std::string>().c_str(), s.value("views_done", 0),
                s.value("views_total", 0));
  if (s.contains("error")) std::printf("  error: %s", s["error"].get<std::string>().c_str());
  std::printf("\n");
}

/// Live progress line until the session leaves "running".
Status follow(Client& c) {
  ProgressLine progress;
  while (true) {
    auto m = c.read_message();
    if (!m) return m.status();
    const json& ev = m.value();
    if (ev.value("event", "") == "progress") {
      progress.update(ev.value("views_done", 0), ev.value("views_total", 0),
                      "  views %d/%d  bracket frame %d (%.4g s)  ETA %.0f s", ev.value("views_done", 0),
                      ev.value("views_total", 0), ev.value("bracket_index", 0), ev.value("exposure_s", 0.0),
                      ev.value("eta_s", 0.0));
    } else if (ev.value("event", "") == "state" && ev.value("state", "") != "running") {
      progress.finish();
      std::printf("%s %s\n", ev.value("session", "").c_str(), ev.value("state", "").c_str());
      if (ev.contains("error")) return make_error(ErrorCode::kDevice, ev["error"].get<std::string>());
      return Status::ok();
    }
  }
}

Status run(const std::string& verb, const SessionArgs& a) {
  Client c;
  VDRIG_TRY(c.connect(a.runtime_dir));
  if (verb == "start" || verb == "resume" || (verb == "status" && a.follow)) {
    if (a.follow || verb == "start") VDRIG_TRY(c.request({{"cmd", "subscribe"}}).status());
  }
  json req = {{"cmd", verb == "list" ? "list-sessions" : verb}};
  if (verb == "start") {
    req["session"] = a.name;
    req["scheme"] = a.scheme;
    req["bracket"] = a.bracket;
    if (!a.scene.empty()) req["scene"] = a.scene;
  } else if (verb == "resume" && !a.name.empty()) {
    req["session"] = a.name;
  }
  auto reply = c.request(req);
  if (!reply) return reply.status();
  if (verb == "list") {
    for (const auto& s : reply.value()["sessions"])
      if (s.value("damaged", false))
        std::printf("%-24s damaged: %s\n", s.value("session", "").c_str(), s.value("reason", "").c_str());
      else
        std::printf("%-24s %4d/%-4d %s %s\n", s.value("session", "").c_str(), s.value("views_done", 0),
                    s.value("views_total", 0), s.value("scheme", "").c_str(), s.value("bracket", "").c_str());
    return Status::ok();
  }
  if (verb == "status") {
    print_status(reply.value());
    if (a.follow && reply.value().value("state", "") == "running") return follow(c);
    return Status::ok();
  }
  if (verb == "start" || (verb == "resume" && a.follow)) return follow(c);
  std::printf("%s\n", reply.value().dump().c_str());
  return Status::ok();
}

struct CheckArgs {
  std::string session;
  bool repair = false;
};

/// One line per problem on stdout; a failure (exit status 1) while any problem is left unrepaired.
Status check(const CheckArgs& a) {
  capture::SessionCheckOptions options;
  options.repair = a.repair;
  auto report = capture::check_session(a.session, options);
  if (!report) return report.status();
  for (const auto& problem : report->problems) std::printf("%s\n", problem.describe().c_str());
  if (!report->views_marked_incomplete.empty()) {
    std::string views;
    for (const int v : report->views_marked_incomplete) views += (views.empty() ? "" : ",") + std::to_string(v);
    std::printf("views %s marked incomplete: vdrig capture --resume %s re-shoots them\n", views.c_str(),
                a.session.c_str());
  }
  const int left = report->unrepaired_count();
  if (left > 0)
    return make_error(ErrorCode::kCorrupt, "session " + a.session + ": " + std::to_string(left) + " problem" +
                                               (left == 1 ? "" : "s") +
                                               (a.repair ? " left" : " (vdrig session check --repair fixes some)"));
  if (report->problems.empty()) std::printf("session %s: ok\n", a.session.c_str());
  return Status::ok();
}

CommandRegistrar reg([](CLI::App& root) {
  auto* session = root.add_subcommand("session", "control capture sessions run by vdrigd");
  session->require_subcommand(1);
  for (const char* verb : {"start", "status", "pause", "resume", "abort", "list"}) {
    auto a = std::make_shared<SessionArgs>();
    auto* cmd = session->add_subcommand(verb, std::string(verb) + " (vdrigd)");
    cmd->add_option("--runtime-dir", a->runtime_dir, "folder of vdrigd.sock")->capture_default_str();
    if (std::string(verb) == "start") {
      cmd->add_option("name", a->name, "session name ([A-Za-z0-9._-])")->required();
      cmd->add_option("--scheme", a->scheme, "sampling scheme")->capture_default_str();
      cmd->add_option("--bracket", a->bracket, "exposure bracket")->capture_default_str();
      cmd->add_option("--scene", a->scene, "simulator scene: a built-in name or a scene FILE.json");
    }
    if (std::string(verb) == "resume") cmd->add_option("name", a->name, "session name (default: the one in hand)");
    if (std::string(verb) == "status" || std::string(verb) == "resume")
      cmd->add_flag("--follow", a->follow, "show live progress until the session stops");
    const std::string v = verb;
    cmd->callback([a, v] { finish(run(v, *a)); });
  }
  auto c = std::make_shared<CheckArgs>();
  auto* cmd = session->add_subcommand(
      "check",
      "check a session folder (frames decode, journal and manifest agree, nothing foreign); exit 1 on a problem");
  cmd->add_option("session", c->session, "session folder")->required();
  cmd->add_flag("--repair", c->repair,
                "under the session lock: mark views with bad frames incomplete (capture --resume re-shoots them), cut "
                "a torn journal line, remove links and stale temporaries");
  cmd->callback([c] { finish(check(*c)); });
});

}  // namespace
}  // namespace vdrig::app

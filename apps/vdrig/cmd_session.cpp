// vdrig session start|status|pause|resume|abort|list: a client of vdrigd (docs/protocol.md); vdrig session check:
// fsck for a session folder (capture/session_check.hpp), run locally.
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/daemon_client.hpp"
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

void print_status(const json& s) {
  std::printf("%s", s.value("state", "?").c_str());
  if (s.contains("session"))
    std::printf("  %s  views %d/%d", s["session"].get<std::string>().c_str(), s.value("views_done", 0),
                s.value("views_total", 0));
  if (s.contains("error")) std::printf("  error: %s", s["error"].get<std::string>().c_str());
  std::printf("\n");
}

/// Live progress line until the session leaves "running".
Status follow(capture::DaemonClient& c) {
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
  capture::DaemonClient c;
  VDRIG_TRY(c.connect(std::filesystem::path(a.runtime_dir) / "vdrigd.sock"));
  if (verb == "start" || verb == "resume" || (verb == "status" && a.follow)) {
    if (a.follow || verb == "start") VDRIG_TRY(c.call({{"cmd", "subscribe"}}).status());
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
  auto reply = c.call(req);
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

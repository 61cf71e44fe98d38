#include "vdrig/capture/daemon.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include "vdrig/capture/plan.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;
using nlohmann::json;

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
  return true;
}

namespace {

/// Strict UTF-8 check (no overlongs, no surrogates, <= U+10FFFF).
bool valid_utf8(const std::string& s) {
  size_t i = 0;
  const size_t n = s.size();
  while (i < n) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      ++i;
      continue;
    }
    int len = 0;
    uint32_t cp = 0;
    if (c >= 0xC2 && c <= 0xDF)
      len = 2, cp = c & 0x1F;
    else if (c >= 0xE0 && c <= 0xEF)
      len = 3, cp = c & 0x0F;
    else if (c >= 0xF0 && c <= 0xF4)
      len = 4, cp = c & 0x07;
    else
      return false;
    if (i + len > n) return false;
    for (int k = 1; k < len; ++k) {
      const unsigned char cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (cc & 0x3F);
    }
    if ((len == 3 && cp < 0x800) || (len == 4 && (cp < 0x10000 || cp > 0x10FFFF)) || (cp >= 0xD800 && cp <= 0xDFFF))
      return false;
    i += len;
  }
  return true;
}

std::string dump_line(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n"; }

enum class RunState { kIdle, kRunning, kPaused, kCompleted, kFailed, kAborted };
const char* state_name(RunState s) {
  switch (s) {
    case RunState::kIdle:
      return "idle";
    case RunState::kRunning:
      return "running";
    case RunState::kPaused:
      return "paused";
    case RunState::kCompleted:
      return "completed";
    case RunState::kFailed:
      return "failed";
    case RunState::kAborted:
      return "aborted";
  }
  return "unknown";
}

enum class StopIntent { kNone, kPause, kAbort, kShutdown };

struct Client {
  int fd = -1;
  std::string in;
  std::string out;
  bool subscribed = false;
  bool closing = false;  // flush `out`, then close
};

/// A request error: answered as {"ok": false, "error": ..., "code": ...}.
struct RequestError {
  std::string code;
  std::string message;
};

}  // namespace

struct Daemon::Impl {
  DaemonConfig config;
  int listen_fd = -1;
  int wake_pipe[2] = {-1, -1};
  std::atomic<bool> stop_flag{false};
  std::map<int, Client> clients;
  std::shared_ptr<spdlog::logger> logger = log::get("vdrigd");

  // Rig: built on demand; used by the worker while it runs, by home/move otherwise.
  std::optional<rig::Rig> rig;
  json rig_config_in_use;

  // Session in hand. Fields below `mutex` are shared with the worker.
  std::thread worker;
  std::atomic<bool> worker_stop{false};
  StopIntent intent = StopIntent::kNone;
  std::mutex mutex;
  RunState state = RunState::kIdle;
  std::string session_name;
  fs::path session_dir;
  CaptureProgress progress;
  std::string last_error, last_error_code;
  std::deque<json> events;
  bool worker_done = false;

  ~Impl() {
    join_worker();
    for (auto& [fd, c] : clients) ::close(fd);
    if (listen_fd >= 0) ::close(listen_fd);
    for (int fd : wake_pipe)
      if (fd >= 0) ::close(fd);
  }

  void wake() {
    const char b = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake_pipe[1], &b, 1);
  }

  void join_worker() {
    if (worker.joinable()) worker.join();
  }

  fs::path socket_path() const { return config.runtime_dir / "vdrigd.sock"; }

  Status start() {
    std::string why;
    if (!config.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "daemon config: " + why);
    if (config.allowed_uid == static_cast<uid_t>(-1)) config.allowed_uid = ::geteuid();
    std::error_code ec;
    fs::create_directories(config.runtime_dir, ec);
    if (ec) return make_error(ErrorCode::kIo, "cannot create " + config.runtime_dir.string() + ": " + ec.message());
    ::chmod(config.runtime_dir.c_str(), 0770);
    fs::create_directories(config.sessions_dir, ec);
    if (ec) return make_error(ErrorCode::kIo, "cannot create " + config.sessions_dir.string() + ": " + ec.message());
    if (::pipe2(wake_pipe, O_NONBLOCK | O_CLOEXEC) != 0)
      return make_error(ErrorCode::kIo, std::string("pipe: ") + std::strerror(errno));

    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string path = socket_path().string();
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    if (fs::exists(socket_path(), ec)) {
      // A live daemon answers a connect; a stale file (crash) does not and is replaced.
      const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
      const bool live = probe >= 0 && ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
      if (probe >= 0) ::close(probe);
      if (live) return make_error(ErrorCode::kInvalidArgument, "another daemon is serving " + path);
      ::unlink(path.c_str());
    }
    listen_fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (listen_fd < 0) return make_error(ErrorCode::kIo, std::string("socket: ") + std::strerror(errno));
    // Bind with a restrictive umask so the socket is never briefly world-accessible, then set exactly 0660.
    const mode_t old_mask = ::umask(0117);
    const int rc = ::bind(listen_fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
    ::umask(old_mask);
    if (rc != 0) return make_error(ErrorCode::kIo, "bind " + path + ": " + std::strerror(errno));
    ::chmod(path.c_str(), 0660);
    if (::listen(listen_fd, 16) != 0) return make_error(ErrorCode::kIo, std::string("listen: ") + std::strerror(errno));
    logger->info("listening on {} (uid {} allowed)", path, config.allowed_uid);
    return Status::ok();
  }

  // --- clients ---

  void send(Client& c, const json& j) {
    if (c.closing && c.fd < 0) return;
    c.out += dump_line(j);
    if (c.out.size() > config.max_output_bytes) {
      logger->warn("client {} is not reading ({} bytes queued): dropped", c.fd, c.out.size());
      c.out.clear();
      c.closing = true;
    }
  }

  void accept_clients() {
    while (true) {
      const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd < 0) return;  // EAGAIN or a transient error: poll again
      ucred cred{};
      socklen_t len = sizeof cred;
      const bool known = ::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) == 0;
      const bool allowed =
          known && (cred.uid == config.allowed_uid || (config.allowed_gid && cred.gid == *config.allowed_gid));
      if (!allowed || static_cast<int>(clients.size()) >= config.max_clients) {
        const std::string reply = dump_line({{"ok", false},
                                             {"code", allowed ? "busy" : "permission_denied"},
                                             {"error", allowed ? "too many clients" : "peer not allowed"}});
        [[maybe_unused]] const ssize_t n = ::send(fd, reply.data(), reply.size(), MSG_NOSIGNAL);
        logger->warn("refused connection from uid {} gid {}", known ? static_cast<long>(cred.uid) : -1L,
                     known ? static_cast<long>(cred.gid) : -1L);
        ::close(fd);
        continue;
      }
      clients[fd].fd = fd;
    }
  }

  /// Reads what is there; returns false when the peer closed or failed.
  bool read_client(Client& c) {
    char buf[16384];
    while (true) {
      const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
      if (n == 0) return false;
      if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
      if (c.closing) continue;  // discard input after a fatal request
      c.in.append(buf, static_cast<size_t>(n));
      size_t pos;
      while (!c.closing && (pos = c.in.find('\n')) != std::string::npos) {
        std::string line = c.in.substr(0, pos);
        c.in.erase(0, pos + 1);
        if (line.size() > config.max_line_bytes) {
          too_long(c);
          break;
        }
        handle_line(c, line);
      }
      if (!c.closing && c.in.size() > config.max_line_bytes) too_long(c);
    }
  }

  void too_long(Client& c) {
    send(c, {{"ok", false},
             {"code", "too_long"},
             {"error", "request longer than " + std::to_string(config.max_line_bytes) + " bytes; closing"}});
    c.in.clear();
    c.closing = true;
  }

  /// Writes queued output; returns false on a write error.
  bool flush_client(Client& c) {
    while (!c.out.empty()) {
      const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL);
      if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
      c.out.erase(0, static_cast<size_t>(n));
    }
    return true;
  }

  // --- requests ---

  void handle_line(Client& c, const std::string& raw) {
    std::string line = raw;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    json id;
    try {
      if (line.empty()) throw RequestError{"bad_request", "empty request"};
      if (!valid_utf8(line)) throw RequestError{"bad_request", "request is not valid UTF-8"};
      json request = json::parse(line, nullptr, false);
      if (request.is_discarded()) throw RequestError{"bad_request", "request is not valid JSON"};
      if (!request.is_object()) throw RequestError{"bad_request", "request must be a JSON object"};
      if (request.contains("id")) {
        if (request["id"].is_string() || request["id"].is_number_integer())
          id = request["id"];
        else
          throw RequestError{"bad_request", "\"id\" must be a string or an integer"};
      }
      if (!request.contains("cmd") || !request["cmd"].is_string())
        throw RequestError{"bad_request", "request needs a string \"cmd\""};
      json reply = dispatch(c, request["cmd"].get<std::string>(), request);
      reply["ok"] = true;
      if (!id.is_null()) reply["id"] = id;
      send(c, reply);
    } catch (const RequestError& e) {
      json reply = {{"ok", false}, {"code", e.code}, {"error", e.message}};
      if (!id.is_null()) reply["id"] = id;
      send(c, reply);
    } catch (const std::exception& e) {
      json reply = {{"ok", false}, {"code", "bad_request"}, {"error", e.what()}};
      if (!id.is_null()) reply["id"] = id;
      send(c, reply);
    }
  }

  static std::string get_string(const json& r, const char* key, const std::string& fallback, bool required = false) {
    if (!r.contains(key)) {
      if (required) throw RequestError{"bad_request", std::string("missing \"") + key + "\""};
      return fallback;
    }
    if (!r[key].is_string()) throw RequestError{"bad_request", std::string("\"") + key + "\" must be a string"};
    return r[key].get<std::string>();
  }

  static double get_number(const json& r, const char* key) {
    if (!r.contains(key)) throw RequestError{"bad_request", std::string("missing \"") + key + "\""};
    if (!r[key].is_number()) throw RequestError{"bad_request", std::string("\"") + key + "\" must be a number"};
    const double v = r[key].get<double>();
    if (!std::isfinite(v)) throw RequestError{"bad_request", std::string("\"") + key + "\" must be finite"};
    return v;
  }

  static void throw_status(const Status& s) {
    if (!s) throw RequestError{to_string(s.error().code), s.error().message};
  }

  static void check_keys(const json& r, std::initializer_list<const char*> allowed) {
    for (auto it = r.begin(); it != r.end(); ++it) {
      bool ok = it.key() == "cmd" || it.key() == "id";
      for (const char* a : allowed) ok = ok || it.key() == a;
      if (!ok) throw RequestError{"bad_request", "unknown field \"" + it.key() + "\""};
    }
  }

  bool running() {
    std::lock_guard lock(mutex);
    return state == RunState::kRunning;
  }

  json dispatch(Client& c, const std::string& cmd, const json& r) {
    if (cmd == "status") {
      check_keys(r, {});
      return status_json();
    }
    if (cmd == "subscribe") {
      check_keys(r, {});
      c.subscribed = true;
      return status_json();
    }
    if (cmd == "start") {
      check_keys(r, {"session", "scheme", "bracket", "scene", "rig"});
      return start_session(r);
    }
    if (cmd == "pause" || cmd == "abort") {
      check_keys(r, {});
      return stop_session(cmd == "pause" ? StopIntent::kPause : StopIntent::kAbort);
    }
    if (cmd == "resume") {
      check_keys(r, {"session"});
      return resume_session(r);
    }
    if (cmd == "list-sessions") {
      check_keys(r, {});
      return list_sessions();
    }
    if (cmd == "home" || cmd == "move") {
      if (cmd == "home")
        check_keys(r, {});
      else
        check_keys(r, {"pan_deg", "tilt_deg"});
      if (running()) throw RequestError{"busy", "a session is running; pause or abort it first"};
      join_worker();
      throw_status(ensure_rig(config.rig_config, false));
      if (cmd == "home") {
        throw_status(rig->stage->home());
      } else {
        const PanTilt target{deg_to_rad(get_number(r, "pan_deg")), deg_to_rad(get_number(r, "tilt_deg"))};
        const rig::StageSpec spec = rig->stage->spec();
        if (target.pan_rad < spec.pan.min_rad - 1e-12 || target.pan_rad > spec.pan.max_rad + 1e-12 ||
            target.tilt_rad < spec.tilt.min_rad - 1e-12 || target.tilt_rad > spec.tilt.max_rad + 1e-12)
          throw RequestError{"invalid_argument", "target outside the axis limits"};
        throw_status(rig->stage->move_to(target));
      }
      auto pos = rig->stage->position();
      if (!pos) throw_status(pos.status());
      return {{"pan_deg", rad_to_deg(pos->pan_rad)}, {"tilt_deg", rad_to_deg(pos->tilt_rad)}};
    }
    throw RequestError{"unknown_command", "unknown command \"" + cmd + "\""};
  }

  json status_json() {
    std::lock_guard lock(mutex);
    json j = {{"state", state_name(state)}};
    if (!session_name.empty()) {
      j["session"] = session_name;
      j["views_done"] = progress.views_done;
      j["views_total"] = progress.views_total;
      j["view"] = progress.view;
      j["bracket_index"] = progress.bracket_index;
      j["exposure_s"] = progress.exposure_s;
      j["eta_s"] = progress.eta_s;
    }
    if (!last_error.empty()) {
      j["error"] = last_error;
      j["error_code"] = last_error_code;
    }
    return j;
  }

  /// Builds the rig for `rc` unless the one in hand already is. `must_match` is false for home/move (any rig).
  Status ensure_rig(const json& rc, bool must_match) {
    if (rig && (!must_match || rc == rig_config_in_use)) return Status::ok();
    rig.reset();
    auto r = config.make_rig(rc);
    if (!r) return r.error();
    rig = std::move(r.value());
    rig_config_in_use = rc;
    return Status::ok();
  }

  json start_session(const json& r) {
    if (running()) throw RequestError{"busy", "a session is running"};
    join_worker();
    const std::string name = get_string(r, "session", "", true);
    std::string why;
    if (!valid_session_name(name, &why)) throw RequestError{"invalid_argument", why};
    const fs::path dir = config.sessions_dir / name;
    if (fs::exists(dir)) throw RequestError{"invalid_argument", "session " + name + " exists; use resume"};
    json rc = config.rig_config;
    if (r.contains("rig")) {
      if (!r["rig"].is_object()) throw RequestError{"bad_request", "\"rig\" must be an object"};
      rc = r["rig"];
    }
    if (r.contains("scene")) {
      const std::string scene = get_string(r, "scene", "");
      if (!rc.contains("sim") || !rc["sim"].is_object())
        throw RequestError{"invalid_argument", "\"scene\" needs a sim rig"};
      rc["sim"]["scene"] = scene;
    }
    throw_status(ensure_rig(rc, true));
    PlanRequest plan;
    plan.rig_config = rc;
    plan.scheme = get_string(r, "scheme", "latlong:6");
    plan.bracket = get_string(r, "bracket", "auto");
    plan.stage = rig->stage->spec();
    auto manifest = plan_manifest(plan);
    if (!manifest) throw_status(manifest.status());
    if (config.describe_surface) config.describe_surface(manifest.value());
    auto session = Session::create(dir, manifest.value());
    if (!session) throw_status(session.status());
    launch(std::move(session.value()), name);
    return {{"session", name},
            {"views_total", manifest->views.size()},
            {"route", manifest->extra.value("route", json::object())}};
  }

  json resume_session(const json& r) {
    if (running()) throw RequestError{"busy", "a session is running"};
    join_worker();
    std::string name;
    {
      std::lock_guard lock(mutex);
      name = session_name;
    }
    if (r.contains("session")) {
      name = get_string(r, "session", "");
      std::string why;
      if (!valid_session_name(name, &why)) throw RequestError{"invalid_argument", why};
    }
    if (name.empty()) throw RequestError{"invalid_argument", "nothing to resume: name a session"};
    auto session = Session::open(config.sessions_dir / name);
    if (!session) throw_status(session.status());
    throw_status(ensure_rig(session->manifest().rig_config, true));
    launch(std::move(session.value()), name);
    return {{"session", name}};
  }

  json stop_session(StopIntent what) {
    std::lock_guard lock(mutex);
    if (state == RunState::kRunning) {
      intent = what;
      worker_stop = true;
      return {{"session", session_name}, {"note", "stopping after the frame in hand"}};
    }
    if (what == StopIntent::kAbort && (state == RunState::kPaused || state == RunState::kFailed)) {
      state = RunState::kAborted;
      events.push_back({{"event", "state"}, {"session", session_name}, {"state", "aborted"}});
      return {{"session", session_name}};
    }
    throw RequestError{"invalid_state", std::string("no running session (state ") + state_name(state) + ")"};
  }

  json list_sessions() {
    json list = json::array();
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(config.sessions_dir, ec)) {
      const std::string name = entry.path().filename().string();
      if (!entry.is_directory() || !valid_session_name(name)) continue;
      auto s = Session::open(entry.path());
      if (!s) continue;
      list.push_back({{"session", name},
                      {"views_total", s->manifest().views.size()},
                      {"views_done", s->completed_view_count()},
                      {"scheme", s->manifest().scheme},
                      {"bracket", s->manifest().bracket}});
    }
    return {{"sessions", list}};
  }

  void launch(Session session, const std::string& name) {
    {
      std::lock_guard lock(mutex);
      state = RunState::kRunning;
      session_name = name;
      session_dir = session.dir();
      progress = {};
      progress.views_total = static_cast<int>(session.manifest().views.size());
      progress.views_done = session.completed_view_count();
      last_error.clear();
      last_error_code.clear();
      intent = StopIntent::kNone;
      worker_done = false;
      events.push_back({{"event", "state"}, {"session", name}, {"state", "running"}});
    }
    worker_stop = false;
    CaptureOptions options = config.capture;
    auto bracket = parse_bracket(session.manifest().bracket);
    if (bracket)
      options.bracket = bracket.value();
    else
      options.exposures_s = session.manifest().exposures_s;
    options.stop_requested = &worker_stop;
    options.on_progress = [this, name](const CaptureProgress& p) {
      std::lock_guard lock(mutex);
      progress = p;
      events.push_back({{"event", "progress"},
                        {"session", name},
                        {"views_done", p.views_done},
                        {"views_total", p.views_total},
                        {"view", p.view},
                        {"bracket_index", p.bracket_index},
                        {"exposure_s", p.exposure_s},
                        {"view_finished", p.view_finished},
                        {"elapsed_s", p.elapsed_s},
                        {"eta_s", p.eta_s}});
      wake();
    };
    worker = std::thread([this, s = std::move(session), options, name]() mutable {
      Status result = Status::ok();
      try {
        result = run_session(*rig, s, options, true);
      } catch (const std::exception& e) {
        result = make_error(ErrorCode::kInternal, std::string("capture threw: ") + e.what());
      }
      {
        std::lock_guard lock(mutex);
        if (result)
          state = RunState::kCompleted;
        else if (result.error().code == ErrorCode::kCancelled)
          state = intent == StopIntent::kAbort ? RunState::kAborted : RunState::kPaused;
        else
          state = RunState::kFailed;
        if (!result) {
          last_error = result.error().message;
          last_error_code = to_string(result.error().code);
        }
        json ev = {{"event", "state"}, {"session", name}, {"state", state_name(state)}};
        if (!result && result.error().code != ErrorCode::kCancelled) {
          ev["error"] = last_error;
          ev["error_code"] = last_error_code;
        }
        events.push_back(ev);
        worker_done = true;
      }
      wake();
    });
  }

  void broadcast_events() {
    std::deque<json> pending;
    {
      std::lock_guard lock(mutex);
      pending.swap(events);
    }
    for (const auto& ev : pending)
      for (auto& [fd, c] : clients)
        if (c.subscribed && !c.closing) send(c, ev);
  }

  Status run() {
    while (!stop_flag.load()) {
      std::vector<pollfd> fds;
      fds.push_back({listen_fd, POLLIN, 0});
      fds.push_back({wake_pipe[0], POLLIN, 0});
      for (auto& [fd, c] : clients) {
        short ev = c.closing ? 0 : POLLIN;
        if (!c.out.empty()) ev |= POLLOUT;
        fds.push_back({fd, ev, 0});
      }
      const int n = ::poll(fds.data(), fds.size(), 1000);
      if (n < 0) {
        if (errno == EINTR) continue;
        return make_error(ErrorCode::kIo, std::string("poll: ") + std::strerror(errno));
      }
      if (fds[1].revents & POLLIN) {
        char buf[256];
        while (::read(wake_pipe[0], buf, sizeof buf) > 0) {
        }
      }
      for (size_t k = 2; k < fds.size(); ++k) {
        auto it = clients.find(fds[k].fd);
        if (it == clients.end()) continue;
        Client& c = it->second;
        bool alive = true;
        if (fds[k].revents & (POLLIN | POLLHUP | POLLERR)) alive = read_client(c);
        if (alive && (fds[k].revents & POLLERR)) alive = false;
        if (!alive) {
          ::close(c.fd);
          clients.erase(it);
        }
      }
      if (fds[0].revents & POLLIN) accept_clients();
      broadcast_events();
      for (auto it = clients.begin(); it != clients.end();) {
        Client& c = it->second;
        const bool ok = flush_client(c);
        if (!ok || (c.closing && c.out.empty())) {
          ::close(c.fd);
          it = clients.erase(it);
        } else {
          ++it;
        }
      }
    }
    shutdown();
    return Status::ok();
  }

  void shutdown() {
    logger->info("shutting down");
    {
      std::lock_guard lock(mutex);
      if (state == RunState::kRunning) {
        intent = StopIntent::kShutdown;
        worker_stop = true;
      }
    }
    join_worker();  // the worker finishes the frame in hand and parks the axes
    if (rig) {
      const Status p = rig->stage->move_to(PanTilt{0.0, 0.0});
      if (!p) logger->warn("parking failed: {}", p.describe());
    }
    broadcast_events();
    for (auto& [fd, c] : clients) {
      (void)flush_client(c);
      ::close(fd);
    }
    clients.clear();
    if (listen_fd >= 0) {
      ::close(listen_fd);
      listen_fd = -1;
      ::unlink(socket_path().c_str());
    }
  }
};

Daemon::Daemon(DaemonConfig config) : impl_(std::make_unique<Impl>()) { impl_->config = std::move(config); }
Daemon::~Daemon() = default;
Status Daemon::start() { return impl_->start(); }
Status Daemon::run() {
  try {
    return impl_->run();
  } catch (const std::exception& e) {
    return make_error(ErrorCode::kInternal, std::string("daemon loop: ") + e.what());
  }
}
void Daemon::request_stop() {
  impl_->stop_flag.store(true);
  if (impl_->wake_pipe[1] >= 0) {
    const char b = 0;
    [[maybe_unused]] const ssize_t n = ::write(impl_->wake_pipe[1], &b, 1);
  }
}
fs::path Daemon::socket_path() const { return impl_->socket_path(); }

}  // namespace vdrig::capture

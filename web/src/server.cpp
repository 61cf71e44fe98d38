#include "vdrig/web/server.hpp"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <optional>
#include <set>
#include <thread>

#include "assets.hpp"
#include "daemon_link.hpp"
#include "guard.hpp"
#include "thumbnail.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/session_layout.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/open_below.hpp"

// Last: httplib.h includes <resolv.h>, whose macro `_res` breaks Eigen's headers (which vdrig's include).
#include <httplib.h>

namespace vdrig::web {
namespace fs = std::filesystem;
using nlohmann::json;

Result<std::string> random_token() {
  unsigned char bytes[24];
  std::size_t got = 0;
  while (got < sizeof bytes) {
    const ssize_t n = ::getrandom(bytes + got, sizeof bytes - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return make_error(ErrorCode::kIo, std::string("getrandom failed: ") + std::strerror(errno));
    got += static_cast<std::size_t>(n);
  }
  static const char* const kHex = "0123456789abcdef";
  std::string token;
  for (const unsigned char b : bytes) token += kHex[b >> 4], token += kHex[b & 15];
  return token;
}

namespace {

/// The files of a session the console serves, by the name the request gives; nothing else of the folder is reachable.
const std::set<std::string>& served_session_files() {
  static const std::set<std::string> names = {
      capture::SessionLayout("").manifest_file().filename().string(),
      capture::SessionLayout("").journal_file().filename().string(),
  };
  return names;
}

std::string_view asset(std::string_view name) {
  for (const Asset& a : assets())
    if (a.name == name) return a.text;
  return {};
}

/// A non-negative decimal index of at most 6 digits, else -1.
int parse_index(const std::string& text) {
  if (text.empty() || text.size() > 6) return -1;
  int v = 0;
  for (const char c : text) {
    if (c < '0' || c > '9') return -1;
    v = v * 10 + (c - '0');
  }
  return v;
}

/// The last `n` lines of `text` (a final newline does not count as a line of its own).
std::string last_lines(const std::string& text, int n) {
  std::size_t at = text.size();
  if (at > 0 && text[at - 1] == '\n') --at;
  for (int i = 0; i < n && at != std::string::npos && at > 0; ++i) at = text.rfind('\n', at - 1);
  return at == std::string::npos || at == 0 ? text : text.substr(at + 1);
}

/// A map's name as SESSION/maps/NAME.exr has it ("phong:1", "hsh:6"), or empty: 1..64 of [A-Za-z0-9:._-], not
/// starting with a dot.
bool valid_map_name(const std::string& name) {
  if (name.size() > 64 || (!name.empty() && name[0] == '.')) return false;
  for (const char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != ':' && c != '.' && c != '_' && c != '-') return false;
  return true;
}

bool wildcard_address(const std::string& address) { return address == "0.0.0.0" || address == "::"; }

void send_json(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& code, const std::string& message) {
  send_json(res, status, {{"ok", false}, {"code", code}, {"error", message}});
}

/// The HTTP status of a daemon's error reply: the request's fault (400), a conflict with the rig's state (409), a
/// missing session (404), else the daemon's or the rig's failure (500).
int http_status_of(const std::string& code) {
  if (code == "bad_request" || code == "invalid_argument" || code == "unknown_command" || code == "too_long")
    return 400;
  if (code == "busy" || code == "invalid_state" || code == "in_use") return 409;
  if (code == "not_found") return 404;
  return 500;
}

}  // namespace

struct Server::Impl {
  ServerOptions options;
  std::string token;
  int port = 0;
  httplib::Server http;
  RateLimiter limiter;
  EventRelay relay;
  std::atomic<int> open_streams{0};
  std::atomic<bool> stop_requested{false}, run_entered{false}, run_exited{false};
  std::shared_ptr<spdlog::logger> logger = log::get("web");

  explicit Impl(ServerOptions o)
      : options(std::move(o)),
        limiter(options.rate_per_s, options.rate_burst),
        relay(options.runtime_dir / "vdrigd.sock") {}

  fs::path socket_path() const { return options.runtime_dir / "vdrigd.sock"; }
  std::string cookie_name() const { return "vdrig_token_" + std::to_string(port); }

  /// The Host values this server answers to: its loopback names and its bound address, at its port. A request
  /// naming another host is refused (403), so that a page of another site whose name was re-pointed at this machine
  /// (DNS rebinding) is not served; a wildcard bind answers any name, and the token alone guards it.
  bool host_allowed(const std::string& host) const {
    if (wildcard_address(options.bind_address)) return true;
    const std::string p = ":" + std::to_string(port);
    const std::string bound =
        options.bind_address.find(':') != std::string::npos ? "[" + options.bind_address + "]" : options.bind_address;
    return host == "127.0.0.1" + p || host == "localhost" + p || host == "[::1]" + p || host == bound + p;
  }

  bool token_matches(const httplib::Request& req, bool header_only) const {
    if (req.has_header("X-Vdrig-Token")) return same_secret(req.get_header_value("X-Vdrig-Token"), token);
    if (header_only) return false;
    if (req.has_param("token")) return same_secret(req.get_param_value("token"), token);
    return same_secret(cookie_value(req.get_header_value("Cookie"), cookie_name()), token);
  }

  /// Every request, before routing: rate (429), Host (403), token (401), and for a POST the token in the header and
  /// the Origin (403). What passes is routed; httplib itself answers a body above the limit with 413.
  httplib::Server::HandlerResponse guard(const httplib::Request& req, httplib::Response& res) {
    using R = httplib::Server::HandlerResponse;
    if (!limiter.allow(req.remote_addr)) {
      res.set_header("Retry-After", "1");
      send_error(res, 429, "rate_limited", "too many requests from " + req.remote_addr);
      return R::Handled;
    }
    const std::string host = req.get_header_value("Host");
    if (!host_allowed(host)) {
      send_error(res, 403, "forbidden", "this server does not answer to host " + host);
      return R::Handled;
    }
    if (!token_matches(req, false)) {
      res.status = 401;
      res.set_content("401: the console needs its token: open the URL that `vdrig serve` printed\n", "text/plain");
      return R::Handled;
    }
    if (req.method != "GET" && req.method != "HEAD") {
      if (!token_matches(req, true)) {
        send_error(res, 403, "forbidden", "a state-changing request needs the token in the X-Vdrig-Token header");
        return R::Handled;
      }
      if (req.get_header_value("Origin") != "http://" + host) {
        send_error(res, 403, "forbidden",
                   "cross-origin request refused (Origin: " + req.get_header_value("Origin") + ")");
        return R::Handled;
      }
    }
    return R::Unhandled;
  }

  void relay_reply(httplib::Response& res, const json& request) {
    auto reply = daemon_request(socket_path(), request, options.daemon_timeout_s);
    if (!reply) {
      const bool late = reply.error().code == ErrorCode::kTimeout;
      send_error(res, late ? 504 : 502, capture::wire_code(reply.error().code), reply.error().message);
      return;
    }
    const json& r = reply.value();
    send_json(res, r.value("ok", false) ? 200 : http_status_of(r.value("code", "")), r);
  }

  /// Whether SESSION/FILE is a regular file, neither the session folder nor the file being a link (as
  /// read_session_file would open it); for the list's links, so that a session without its report links none.
  bool session_file_exists(const std::string& session, const std::string& file) const {
    if (options.sessions_dir.empty() || !capture::valid_session_name(session)) return false;
    const int dir = ::open((options.sessions_dir / session).c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (dir < 0) return false;
    struct stat st {};
    const bool regular = ::fstatat(dir, file.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(st.st_mode);
    ::close(dir);
    return regular;
  }

  /// The daemon's list of sessions, each sound one with "report": whether its report.html is there to be served.
  void serve_sessions(httplib::Response& res) {
    auto reply = daemon_request(socket_path(), {{"cmd", "list-sessions"}}, options.daemon_timeout_s);
    if (!reply) {
      const bool late = reply.error().code == ErrorCode::kTimeout;
      send_error(res, late ? 504 : 502, capture::wire_code(reply.error().code), reply.error().message);
      return;
    }
    json r = std::move(reply).value();
    if (r.contains("sessions") && r["sessions"].is_array())
      for (auto& s : r["sessions"])
        if (s.is_object() && !s.value("damaged", false))
          s["report"] = session_file_exists(s.value("session", ""), "report.html");
    send_json(res, r.value("ok", false) ? 200 : http_status_of(r.value("code", "")), r);
  }

  /// The JSON object body of a POST with only string fields among `fields`; nullopt (and a 400 sent) otherwise.
  std::optional<json> string_fields(const httplib::Request& req, httplib::Response& res,
                                    const std::vector<std::string>& fields) {
    json body = req.body.empty() ? json::object() : json::parse(req.body, nullptr, false);
    if (body.is_discarded() || !body.is_object()) {
      send_error(res, 400, "bad_request", "the body must be a JSON object");
      return std::nullopt;
    }
    json out = json::object();
    for (const auto& [key, value] : body.items()) {
      if (std::find(fields.begin(), fields.end(), key) == fields.end()) {
        send_error(res, 400, "bad_request", "unknown field " + key);
        return std::nullopt;
      }
      if (!value.is_string()) {
        send_error(res, 400, "bad_request", "field " + key + " must be a string");
        return std::nullopt;
      }
      if (!value.get<std::string>().empty()) out[key] = value;  // an empty form field: the daemon's default
    }
    return out;
  }

  /// The JSON object body of a POST with exactly `fields`, each a finite number; nullopt (and a 400 sent) otherwise.
  std::optional<json> number_fields(const httplib::Request& req, httplib::Response& res,
                                    const std::vector<std::string>& fields) {
    const json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded() || !body.is_object()) {
      send_error(res, 400, "bad_request", "the body must be a JSON object");
      return std::nullopt;
    }
    for (const auto& [key, value] : body.items())
      if (std::find(fields.begin(), fields.end(), key) == fields.end()) {
        send_error(res, 400, "bad_request", "unknown field " + key);
        return std::nullopt;
      }
    json out = json::object();
    for (const auto& f : fields) {
      if (!body.contains(f) || !body[f].is_number() || !std::isfinite(body[f].get<double>())) {
        send_error(res, 400, "bad_request", "field " + f + " must be a number");
        return std::nullopt;
      }
      out[f] = body[f].get<double>();
    }
    return out;
  }

  void serve_asset(httplib::Response& res, std::string_view name, const std::string& type) {
    res.set_content(std::string(asset(name)), type);
  }

  void serve_page(const httplib::Request& req, httplib::Response& res) {
    if (req.has_param("token")) {
      // The first load: the token goes into a cookie, and the page is loaded again without it in the address.
      res.set_header("Set-Cookie", cookie_name() + "=" + token + "; Path=/; HttpOnly; SameSite=Strict");
      res.set_redirect("/", 303);
      return;
    }
    std::string page(asset("index.html"));
    const std::string mark = "{{TOKEN}}";
    const auto at = page.find(mark);
    if (at != std::string::npos) page.replace(at, mark.size(), token);
    res.set_content(page, "text/html; charset=utf-8");
  }

  /// Whether `session` is a session name the daemon lists, undamaged (false without a sessions folder or for a name
  /// that is not one); the daemon's failure when it cannot list the sessions.
  Result<bool> session_listed(const std::string& session) {
    if (options.sessions_dir.empty() || !capture::valid_session_name(session)) return false;
    auto listing = daemon_request(socket_path(), {{"cmd", "list-sessions"}}, options.daemon_timeout_s);
    if (!listing) return listing.error();
    for (const auto& s : listing.value().value("sessions", json::array()))
      if (s.value("session", "") == session && !s.value("damaged", false)) return true;
    return false;
  }

  /// The bytes of a file of a listed session: `parts` are fixed names built here (never taken from the request), opened
  /// one step at a time from the sessions folder without following a link. kNotFound for anything else, so that a
  /// request cannot tell a missing file from a refused one; the daemon's failure when it cannot list the sessions.
  Result<std::string> read_session_file(const std::string& session, const std::vector<std::string>& parts,
                                        std::size_t max_bytes = std::size_t{64} << 20) {
    const Error missing = make_error(ErrorCode::kNotFound, "no such file");
    auto listed = session_listed(session);
    if (!listed) return listed.error();
    if (!listed.value()) return missing;
    struct stat st {};
    const int fd = open_regular_below(options.sessions_dir / session, parts, st);
    if (fd < 0) return missing;
    if (static_cast<std::size_t>(st.st_size) > max_bytes) {
      ::close(fd);
      return missing;
    }
    std::string text(static_cast<std::size_t>(st.st_size), '\0');
    std::size_t done = 0;
    while (done < text.size()) {
      const ssize_t n = ::read(fd, text.data() + done, text.size() - done);
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    ::close(fd);
    text.resize(done);
    return text;
  }

  void send_failure(httplib::Response& res, const Error& e) {
    if (e.code == ErrorCode::kNotFound) return send_error(res, 404, "not_found", e.message);
    const bool late = e.code == ErrorCode::kTimeout;
    send_error(res, late ? 504 : 502, capture::wire_code(e.code), e.message);
  }

  /// The folder of a listed session, by its name only; kNotFound for another name or a linked folder.
  Result<fs::path> listed_session_dir(const std::string& session) {
    const Error missing = make_error(ErrorCode::kNotFound, "no such session");
    auto listed = session_listed(session);
    if (!listed) return listed.error();
    const fs::path dir = options.sessions_dir / session;
    std::error_code ec;
    if (!listed.value() || !fs::is_directory(fs::symlink_status(dir, ec))) return missing;
    return dir;
  }

  /// The WebGL2 viewer's scene of a finished session: its map's GLSL and parameters, camera and poses.
  void serve_viewer_scene(const httplib::Request& req, httplib::Response& res) {
    if (!options.viewer_scene)
      return send_error(res, 501, "unsupported", "this vdrig is built without the post-capture modules");
    const std::string map = req.get_param_value("map");
    if (!valid_map_name(map)) return send_error(res, 400, "bad_request", "a map name is [A-Za-z0-9:._-]");
    auto dir = listed_session_dir(req.get_param_value("session"));
    if (!dir) return send_failure(res, dir.error());
    auto scene = options.viewer_scene(dir.value(), map);
    if (!scene) {
      const bool missing = scene.error().code == ErrorCode::kNotFound;
      return send_error(res, missing ? 404 : 500, capture::wire_code(scene.error().code), scene.error().message);
    }
    json j = std::move(scene.value().scene);
    j["ok"] = true;
    j["params_base64"] = base64(scene.value().params_f32);
    send_json(res, 200, j);
  }

  void serve_viewer_photo(const httplib::Request& req, httplib::Response& res) {
    if (!options.viewer_photo)
      return send_error(res, 501, "unsupported", "this vdrig is built without the post-capture modules");
    const int view = parse_index(req.get_param_value("view"));
    if (view < 0) return send_error(res, 400, "bad_request", "view must be an index");
    auto dir = listed_session_dir(req.get_param_value("session"));
    if (!dir) return send_failure(res, dir.error());
    auto png = options.viewer_photo(dir.value(), view, 1.0);
    if (!png) {
      const bool missing = png.error().code == ErrorCode::kNotFound;
      return send_error(res, missing ? 404 : 500, capture::wire_code(png.error().code), png.error().message);
    }
    res.set_content(png.value(), "image/png");
  }

  /// The texel inspector's plot of a texel of a map (the curve `vdrig view` draws on a click), as SVG: by session
  /// name, map name and texel indices (decimal, else 400; outside the map 400), served as an image (the page shows it
  /// in an <img>, where an SVG's scripts do not run).
  void serve_viewer_texel(const httplib::Request& req, httplib::Response& res) {
    if (!options.viewer_texel)
      return send_error(res, 501, "unsupported", "this vdrig is built without the post-capture modules");
    const std::string map = req.get_param_value("map");
    if (!valid_map_name(map)) return send_error(res, 400, "bad_request", "a map name is [A-Za-z0-9:._-]");
    const int s = parse_index(req.get_param_value("s")), t = parse_index(req.get_param_value("t"));
    if (s < 0 || t < 0) return send_error(res, 400, "bad_request", "s and t must be texel indices (decimal, >= 0)");
    auto dir = listed_session_dir(req.get_param_value("session"));
    if (!dir) return send_failure(res, dir.error());
    auto svg = options.viewer_texel(dir.value(), map, s, t);
    if (!svg) {
      const ErrorCode code = svg.error().code;
      const int status = code == ErrorCode::kNotFound ? 404 : code == ErrorCode::kInvalidArgument ? 400 : 500;
      return send_error(res, status, capture::wire_code(code), svg.error().message);
    }
    res.set_content(svg.value(), "image/svg+xml");
  }

  /// A session's report (`vdrig report S --out S/report.html`): the page vdrig wrote, with its inline styles and
  /// scripts, served sandboxed (an opaque origin: its scripts cannot use the console's cookie or API).
  void serve_report(const std::string& session, httplib::Response& res) {
    auto text = read_session_file(session, {"report.html"}, std::size_t{256} << 20);
    if (!text) return send_failure(res, text.error());
    res.headers.erase("Content-Security-Policy");  // the default one, replaced: a second would be enforced too
    res.set_header("Content-Security-Policy",
                   "sandbox allow-scripts; default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
                   "img-src data:; font-src data:; frame-ancestors 'none'");
    res.set_content(std::move(text).value(), "text/html; charset=utf-8");
  }

  /// A session's manifest or journal, by session name and file name only (one of served_session_files()). `tail`
  /// keeps the journal's last lines only (the page's log).
  void serve_session_file(const std::string& session, const std::string& file, int tail, httplib::Response& res) {
    if (!served_session_files().count(file)) return send_error(res, 404, "not_found", "no such file");
    auto text = read_session_file(session, {file});
    if (!text) return send_failure(res, text.error());
    std::string body = std::move(text).value();
    if (tail > 0) body = last_lines(body, tail);
    res.set_content(body, file.ends_with(".json") ? "application/json" : "text/plain; charset=utf-8");
  }

  /// A frame of a session as the page's thumbnail (frame_thumbnail): by session name, view and bracket index.
  void serve_frame(const httplib::Request& req, httplib::Response& res) {
    const std::string session = req.get_param_value("session");
    const int view = parse_index(req.get_param_value("view"));
    const int bracket = parse_index(req.get_param_value("bracket"));
    if (view < 0 || bracket < 0) return send_error(res, 400, "bad_request", "view and bracket must be indices");
    const fs::path relative = capture::SessionLayout::frame_file_relative(view, bracket);
    std::vector<std::string> parts;
    for (const auto& p : relative) parts.push_back(p.string());
    auto bytes = read_session_file(session, parts);
    if (!bytes) return send_failure(res, bytes.error());
    auto thumb = frame_thumbnail(bytes.value(), relative.string(), kThumbnailWidth);
    if (!thumb) return send_error(res, 500, capture::wire_code(thumb.error().code), thumb.error().message);
    json j = thumb.value();
    j["ok"] = true;
    j["session"] = session;
    j["view"] = view;
    j["bracket_index"] = bracket;
    send_json(res, 200, j);
  }

  void serve_events(httplib::Response& res) {
    if (open_streams.fetch_add(1) >= options.max_event_streams) {
      open_streams.fetch_sub(1);
      send_error(res, 503, "busy", "too many open event streams");
      return;
    }
    auto queue = relay.subscribe();
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [queue, first = true](size_t, httplib::DataSink& sink) mutable {
          if (first) {
            first = false;
            const std::string retry = "retry: 1000\n\n";
            return sink.write(retry.data(), retry.size());
          }
          std::string line;
          if (!queue->pop(line, std::chrono::seconds(5))) return false;  // the server stops
          // A comment when nothing happened: keeps proxies from timing the stream out, and finds a page that went away
          // (the write fails) within seconds, so that its worker and stream slot are freed.
          const std::string chunk = line.empty() ? std::string(": idle\n\n") : "data: " + line + "\n\n";
          return sink.write(chunk.data(), chunk.size());
        },
        [this, queue](bool) {
          relay.unsubscribe(queue);
          open_streams.fetch_sub(1);
        });
  }

  void routes() {
    http.new_task_queue = [n = options.worker_threads] { return new httplib::ThreadPool(static_cast<size_t>(n)); };
    http.set_payload_max_length(options.max_body_bytes);
    http.set_keep_alive_timeout(2);  // an idle keep-alive connection holds a worker: not for long
    http.set_read_timeout(5);
    http.set_default_headers({
        {"Cache-Control", "no-store"},
        {"X-Content-Type-Options", "nosniff"},
        {"X-Frame-Options", "DENY"},
        // same-origin, not no-referrer: with no-referrer a browser sends "Origin: null" on the page's own POSTs.
        {"Referrer-Policy", "same-origin"},
        {"Content-Security-Policy",
         "default-src 'none'; script-src 'self'; style-src 'self'; connect-src 'self'; img-src 'self' data:; "
         "base-uri 'none'; form-action 'none'; frame-ancestors 'none'"},
    });
    http.set_pre_routing_handler(
        [this](const httplib::Request& req, httplib::Response& res) { return guard(req, res); });
    http.set_logger([this](const httplib::Request& req, const httplib::Response& res) {
      logger->debug("{} {} {} -> {}", req.remote_addr, req.method, req.path, res.status);
    });
    http.Get("/", [this](const httplib::Request& req, httplib::Response& res) { serve_page(req, res); });
    http.Get("/static/app.js", [this](const httplib::Request&, httplib::Response& res) {
      serve_asset(res, "app.js", "text/javascript; charset=utf-8");
    });
    http.Get("/static/style.css", [this](const httplib::Request&, httplib::Response& res) {
      serve_asset(res, "style.css", "text/css; charset=utf-8");
    });
    http.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
      relay_reply(res, {{"cmd", "status"}});
    });
    http.Get("/api/sessions", [this](const httplib::Request&, httplib::Response& res) { serve_sessions(res); });
    http.Get("/api/events", [this](const httplib::Request&, httplib::Response& res) { serve_events(res); });
    http.Get(R"(/files/([^/]+)/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
      const int tail = req.has_param("tail") ? std::min(parse_index(req.get_param_value("tail")), 1000) : 0;
      serve_session_file(req.matches[1], req.matches[2], tail, res);
    });
    http.Get("/api/frame", [this](const httplib::Request& req, httplib::Response& res) { serve_frame(req, res); });
    http.Get("/api/viewer/scene",
             [this](const httplib::Request& req, httplib::Response& res) { serve_viewer_scene(req, res); });
    http.Get("/api/viewer/photo",
             [this](const httplib::Request& req, httplib::Response& res) { serve_viewer_photo(req, res); });
    http.Get("/api/viewer/texel",
             [this](const httplib::Request& req, httplib::Response& res) { serve_viewer_texel(req, res); });
    http.Get(R"(/report/([^/]+))",
             [this](const httplib::Request& req, httplib::Response& res) { serve_report(req.matches[1], res); });
    http.Get("/viewer", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(std::string(asset("viewer.html")), "text/html; charset=utf-8");
    });
    http.Get("/static/viewer.js", [this](const httplib::Request&, httplib::Response& res) {
      serve_asset(res, "viewer.js", "text/javascript; charset=utf-8");
    });
    // The commands, each with the daemon's own fields: the daemon validates them and its error text is relayed.
    http.Post("/api/start", [this](const httplib::Request& req, httplib::Response& res) {
      auto fields = string_fields(req, res, {"session", "scheme", "bracket", "scene"});
      if (!fields) return;
      json request = fields.value();
      request["cmd"] = "start";
      relay_reply(res, request);
    });
    http.Post("/api/resume", [this](const httplib::Request& req, httplib::Response& res) {
      auto fields = string_fields(req, res, {"session"});
      if (!fields) return;
      json request = fields.value();
      request["cmd"] = "resume";
      relay_reply(res, request);
    });
    // The stage, as `vdrig session` could move it: home, and move to an absolute pan/tilt the daemon checks against
    // the axis limits (the page's jog buttons send the last known position plus a step).
    http.Post("/api/move", [this](const httplib::Request& req, httplib::Response& res) {
      auto target = number_fields(req, res, {"pan_deg", "tilt_deg"});
      if (!target) return;
      json request = target.value();
      request["cmd"] = "move";
      relay_reply(res, request);
    });
    for (const char* verb : {"pause", "abort", "stop", "home"}) {
      http.Post(std::string("/api/") + verb, [this, verb](const httplib::Request& req, httplib::Response& res) {
        if (!string_fields(req, res, {})) return;
        relay_reply(res, {{"cmd", verb}});
      });
    }
  }
};

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() {
  if (impl_) stop();
}

Result<std::unique_ptr<Server>> Server::create(ServerOptions options) {
  std::vector<std::string> why;
  if (options.port < 0 || options.port > 65535) why.push_back("port must be 0..65535");
  if (options.runtime_dir.empty()) why.push_back("no runtime folder");
  if (options.bind_address.empty()) why.push_back("no address to bind");
  if (options.worker_threads < 2) why.push_back("worker_threads must be at least 2");
  if (options.max_event_streams < 1 || options.max_event_streams >= options.worker_threads)
    why.push_back("max_event_streams must be 1..worker_threads-1 (a stream holds a worker)");
  if (!(options.rate_per_s > 0) || !(options.rate_burst >= 1)) why.push_back("rate_per_s > 0 and rate_burst >= 1");
  if (!options.token.empty() && options.token.size() < 16) why.push_back("a token needs 16 characters at least");
  if (!why.empty()) {
    std::string text;
    for (const auto& w : why) text += (text.empty() ? "" : "; ") + w;
    return make_error(ErrorCode::kInvalidArgument, "vdrig serve: " + text);
  }
  if (options.token.empty()) {
    auto token = random_token();
    if (!token) return token.error();
    options.token = token.value();
  }
  auto impl = std::make_unique<Impl>(std::move(options));
  impl->token = impl->options.token;
  impl->routes();
  const std::string& address = impl->options.bind_address;
  if (impl->options.port == 0) {
    impl->port = impl->http.bind_to_any_port(address);
    if (impl->port <= 0) return make_error(ErrorCode::kIo, "cannot bind " + address + ": " + std::strerror(errno));
  } else {
    if (!impl->http.bind_to_port(address, impl->options.port))
      return make_error(ErrorCode::kIo, "cannot bind " + address + ":" + std::to_string(impl->options.port) + ": " +
                                            std::strerror(errno));
    impl->port = impl->options.port;
  }
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

int Server::port() const { return impl_->port; }
const std::string& Server::token() const { return impl_->token; }

std::string Server::url() const {
  const std::string& a = impl_->options.bind_address;
  const std::string host = wildcard_address(a) ? "127.0.0.1" : a.find(':') != std::string::npos ? "[" + a + "]" : a;
  return "http://" + host + ":" + std::to_string(impl_->port) + "/?token=" + impl_->token;
}

Status Server::run() {
  impl_->run_entered = true;
  if (impl_->stop_requested) {
    impl_->run_exited = true;
    return Status::ok();
  }
  impl_->relay.start();
  const bool listened = impl_->http.listen_after_bind();
  impl_->run_exited = true;
  impl_->relay.stop();
  if (!listened) return make_error(ErrorCode::kIo, "the web server stopped listening");
  return Status::ok();
}

void Server::stop() {
  impl_->stop_requested = true;
  impl_->relay.stop();  // first: the event streams end, so their workers are free when the pool joins
  // httplib's stop() does nothing before its loop runs: wait for run() to get there (or to have ended).
  if (impl_->run_entered)
    while (!impl_->http.is_running() && !impl_->run_exited) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  impl_->http.stop();
}

}  // namespace vdrig::web

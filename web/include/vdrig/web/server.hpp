// vdrig serve: a web console for vdrigd (docs/web.md). The server is a client of the daemon's Unix socket
// (docs/protocol.md) and can do nothing that protocol does not allow; it never drives the rig itself.
//
// Every request needs the token (the page's first load carries it in the query, as Jupyter's does, and gets it back
// as a cookie); a state-changing request is a POST with the token in the X-Vdrig-Token header and an Origin of this
// server. Files are served only from the sessions folder, by session name (checked, and looked up in the daemon's
// list) and a fixed file name, never by a path taken from the request. Bodies above max_body_bytes get 413, and a
// client address past its rate 429.
//
// Threads: run() serves on the calling thread with a small pool of workers (each Server-Sent Events stream holds one
// while it is open, so their number is capped); one more thread holds the daemon's event subscription and relays it.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::web {

/// What the WebGL2 viewer of a finished session needs (pipeline::web_scene, docs/web.md): the map's model GLSL,
/// texel grid, surface size, the session's camera and captured poses as JSON, and the parameter layers as
/// little-endian float32 RGBA (layer l holds map channels 4l..4l+3, rows of texels).
struct ViewerScene {
  nlohmann::json scene;
  std::string params_f32;
};
/// The viewer's data of a session folder (built by the server from a listed session's name) and a map name already
/// checked (`[A-Za-z0-9:._-]`, empty: the first map). Left unset in a build without the post-capture modules.
using ViewerSceneFn = std::function<Result<ViewerScene>(const std::filesystem::path& session_dir, const std::string&)>;
/// A captured view's HDR photograph tone-mapped (y = 1 - exp(-gamma x), sRGB) as PNG bytes.
using ViewerPhotoFn = std::function<Result<std::string>(const std::filesystem::path& session_dir, int view, double)>;
/// The texel inspector's curve plot of texel (s, t) of a map (name checked as above) as SVG (pipeline::web_texel_svg);
/// kInvalidArgument for a texel outside the map, kNotFound for a missing map or observation map.
using ViewerTexelFn =
    std::function<Result<std::string>(const std::filesystem::path& session_dir, const std::string&, int s, int t)>;

struct ServerOptions {
  std::filesystem::path runtime_dir;  ///< the daemon's folder: runtime_dir/vdrigd.sock
  /// The daemon's --sessions-dir: session files are served from here only (none when empty).
  std::filesystem::path sessions_dir;
  std::string bind_address = "127.0.0.1";
  int port = 0;                            ///< 0: a free port the system picks
  std::string token;                       ///< empty: a random one (random_token())
  std::size_t max_body_bytes = 16 * 1024;  ///< a larger request body is refused with 413
  double rate_per_s = 20;                  ///< requests per second one client address may make on average ...
  double rate_burst = 100;                 ///< ... and at once; past that 429 (a token bucket per address)
  int max_event_streams = 6;               ///< open /api/events streams (each holds a worker); more get 503
  int worker_threads = 12;       ///< below the daemon's 16 connections per uid: one per request, plus the relay's
  double daemon_timeout_s = 30;  ///< a daemon reply (`start` plans the route first) or it is 504
  ViewerSceneFn viewer_scene;    ///< unset: /api/viewer/* answer 501
  ViewerPhotoFn viewer_photo;
  ViewerTexelFn viewer_texel;
};

/// 24 bytes from the system's random source as 48 hex digits.
Result<std::string> random_token();

class Server {
 public:
  /// Validates the options and binds the address (kInvalidArgument / kIo with the reason). Does not need the daemon
  /// to be running: requests made while it is not get 502 and the event stream reports it as disconnected.
  static Result<std::unique_ptr<Server>> create(ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  int port() const;
  const std::string& token() const;
  /// http://HOST:PORT/?token=TOKEN (HOST: the bound address; 127.0.0.1 for a wildcard bind).
  std::string url() const;

  /// Serves until stop(); kIo when the server could not listen.
  Status run();
  /// Thread-safe: ends run() and closes the event streams.
  void stop();

  struct Impl;

 private:
  explicit Server(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vdrig::web

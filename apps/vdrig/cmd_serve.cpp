// vdrig serve: the web console (web/, docs/web.md), a client of the vdrigd on --runtime-dir. Prints its URL with the
// token first, as Jupyter does, and serves until SIGINT or SIGTERM.
#include <signal.h>

#include <cstdio>
#include <string>
#include <thread>

#include "commands.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/web/server.hpp"
#ifdef VDRIG_SERVE_VIEWER  // built with the post-capture modules: the page's WebGL2 viewer of finished sessions
#include "vdrig/core/image_codec.hpp"
#include "vdrig/pipeline/web_scene.hpp"
#include "vdrig/viewer/surface_renderer.hpp"
#endif

namespace vdrig::app {
namespace {

struct ServeArgs {
  std::string runtime_dir = capture::default_runtime_dir().string();
  std::string sessions_dir;
  std::string bind = "127.0.0.1";
  int port = 8765;
};

Status serve(const ServeArgs& a) {
  web::ServerOptions options;
  options.runtime_dir = a.runtime_dir;
  options.sessions_dir = a.sessions_dir;
  options.bind_address = a.bind;
  options.port = a.port;
#ifdef VDRIG_SERVE_VIEWER
  options.viewer_scene = [](const std::filesystem::path& dir, const std::string& map) -> Result<web::ViewerScene> {
    auto scene = pipeline::web_scene(dir, map);
    if (!scene) return scene.error();
    const auto& p = scene->params;
    return web::ViewerScene{std::move(scene->scene),
                            std::string(reinterpret_cast<const char*>(p.data()), p.size() * sizeof(float))};
  };
  options.viewer_photo = [](const std::filesystem::path& dir, int view, double gamma) -> Result<std::string> {
    auto radiance = pipeline::web_photo(dir, view);
    if (!radiance) return radiance.error();
    return encode_png(viewer::tone_map(radiance.value(), gamma));
  };
  options.viewer_texel = pipeline::web_texel_svg;
#endif
  // SIGINT and SIGTERM are taken by a thread of their own (sigwait), blocked before any server thread starts so
  // that every thread inherits the mask: stopping the server is not async-signal-safe.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  auto server = web::Server::create(options);
  if (!server) return server.status();
  if (a.bind != "127.0.0.1" && a.bind != "::1" && a.bind != "localhost")
    log::get("web")->warn("serving on {}: anyone who can reach it and has the token controls the rig", a.bind);
  std::printf("%s\n", server.value()->url().c_str());
  std::fflush(stdout);
  web::Server& s = *server.value();
  std::thread watcher([&s, signals] {
    int signal = 0;
    sigwait(&signals, &signal);
    s.stop();
  });
  const Status served = s.run();
  pthread_kill(watcher.native_handle(), SIGTERM);  // run() may have ended by itself: let the watcher go
  watcher.join();
  return served;
}

CommandRegistrar reg([](CLI::App& root) {
  auto a = std::make_shared<ServeArgs>();
  auto* cmd = root.add_subcommand(
      "serve", "web console for vdrigd: sessions, start/pause/resume/abort, live progress, home/jog, results");
  cmd->add_option("--runtime-dir", a->runtime_dir, "folder of vdrigd.sock")->capture_default_str();
  cmd->add_option("--sessions-dir", a->sessions_dir, "vdrigd's sessions folder, whose session files the page links");
  cmd->add_option("--port", a->port, "TCP port (0: any free one)")->capture_default_str()->check(CLI::Range(0, 65535));
  cmd->add_option("--bind", a->bind, "address to listen on (loopback unless another is asked for)")
      ->capture_default_str();
  cmd->callback([a] { finish(serve(*a)); });
});

}  // namespace
}  // namespace vdrig::app

// vdrigd: runs capture sessions on the configured rig, controlled over a Unix socket (docs/protocol.md).
#include <signal.h>

#include <CLI/CLI.hpp>
#include <cstdio>

#include "rig_backends.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/log.hpp"

namespace {
vdrig::capture::Daemon* g_daemon = nullptr;
extern "C" void on_signal(int) {
  if (g_daemon) g_daemon->request_stop();  // async-signal-safe: an atomic store and a pipe write
}
}  // namespace

int main(int argc, char** argv) {
  using namespace vdrig;
  CLI::App app{"vdrigd: the vdrig capture daemon"};
  std::string runtime_dir = capture::default_runtime_dir().string();
  std::string sessions_dir;
  std::string rig_file;
  std::string geometry_file;
  std::string scene = "patchwork";
  std::string level = "info";
  long allowed_gid = -1;
  double reserve_mb = 256;
  capture::RetryPolicy retry;
  app.add_option("--runtime-dir", runtime_dir, "folder of the control socket vdrigd.sock")->capture_default_str();
  app.add_option("--sessions-dir", sessions_dir, "folder holding the sessions")->required();
  app.add_option("--rig", rig_file, "rig config JSON (default: the simulator, when built)");
  app.add_option("--scene", scene, "simulator scene (a built-in name or a scene FILE.json) when no --rig is given")
      ->capture_default_str();
  app.add_option("--geometry", geometry_file,
                 "a calibration's views.json: its kinematic fit becomes the rig config's \"geometry\" (planning aims "
                 "with it)");
  app.add_option("--allowed-gid", allowed_gid, "also accept clients of this group");
  app.add_option("--reserve-mb", reserve_mb, "free disk space to keep, MiB")->capture_default_str();
  app.add_option("--log-level", level, log::kLevelNames)->capture_default_str();
  app.add_option("--device-attempts", retry.max_attempts,
                 "attempts of a device call (stage, camera) before a session stops with the fault")
      ->capture_default_str();
  app.add_option("--backoff-s", retry.initial_backoff_s, "wait before the first retry (doubles after each)")
      ->capture_default_str();
  app.add_option("--max-backoff-s", retry.max_backoff_s, "longest wait between retries")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (auto s = log::set_level(level); !s) {
    std::fprintf(stderr, "vdrigd: %s\n", s.error().message.c_str());
    return 2;
  }
  auto logger = log::get("vdrigd");
  auto reserve = capture::disk_reserve_bytes_from_mib(reserve_mb);
  if (!reserve) {
    logger->error("{}", reserve.error().message);
    return 2;
  }

  capture::DaemonConfig config;
  config.runtime_dir = runtime_dir;
  config.sessions_dir = sessions_dir;
  if (allowed_gid >= 0) config.allowed_gid = static_cast<gid_t>(allowed_gid);
  config.capture.disk_reserve_bytes = reserve.value();
  config.capture.retry = retry;
  if (retry.max_attempts < 1 || !(retry.initial_backoff_s >= 0) || !(retry.max_backoff_s >= 0)) {
    logger->error("--device-attempts must be >= 1 and the backoffs >= 0");
    return 2;
  }
  if (!rig_file.empty()) {
    auto file = read_json_file(rig_file);
    if (!file) {
      logger->error("cannot read rig config: {}", file.error().message);
      return 2;
    }
    config.rig_config = std::move(file.value());
  } else {
    auto simulated = app::simulated_rig_config(scene);
    if (!simulated) {
      logger->error("--rig: {}", simulated.error().message);
      return 2;
    }
    config.rig_config = std::move(simulated.value());
  }
  if (!geometry_file.empty()) {
    auto fitted = capture::with_fitted_geometry(config.rig_config, geometry_file);
    if (!fitted) {
      logger->error("--geometry: {}", fitted.error().message);
      return 2;
    }
    config.rig_config = std::move(fitted.value());
  }
  // The geometry is checked now, not at the first start request.
  if (auto g = capture::geometry_from_rig_config(config.rig_config); !g) {
    logger->error("{}", g.error().message);
    return 2;
  }
  auto registry = std::make_shared<rig::BackendRegistry>(app::rig_backends());
  config.make_rig = [registry](const nlohmann::json& rc) { return registry->make_rig(rc); };
  config.describe_surface = [](capture::Manifest& m) {
    // An unreadable scene fails make_rig, which reports it; the manifest keeps its defaults meanwhile.
    auto surface = app::simulated_surface_size(m.rig_config);
    if (surface && surface.value()) {
      m.surface_width_mm = surface.value()->width_mm;
      m.surface_height_mm = surface.value()->height_mm;
    }
  };

  capture::Daemon daemon(config);
  if (const Status s = daemon.start(); !s) {
    logger->error("{}", s.describe());
    // A rig another process drives is a start refused, as a bad config is: no point in restarting it as is.
    return s.error().code == ErrorCode::kInvalidArgument || s.error().code == ErrorCode::kInUse ? 2 : 1;
  }
  g_daemon = &daemon;
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  const Status s = daemon.run();
  g_daemon = nullptr;
  if (!s) {
    logger->error("{}", s.describe());
    return 1;
  }
  return 0;
}

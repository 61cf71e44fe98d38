// vdrigd's request path without a socket: each input line goes through Protocol::answer (UTF-8, JSON, the command
// table, the handlers) to a SessionRunner on a small simulated rig in a private sessions folder. Every reply must be
// an object with a boolean "ok". After the lines the runner is shut down and the sessions folder emptied, so inputs
// do not see each other's sessions.
#include <chrono>
#include <optional>
#include <string_view>
#include <thread>

#include "daemon_protocol.hpp"
#include "fuzz_support.hpp"
#include "session_runner.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/sim_rig.hpp"

using namespace vdrig;
using nlohmann::json;

namespace {

constexpr int kMaxLines = 8;
constexpr long long kMaxCameraPixels = 64 * 64;  // a request's "rig" may name any camera: keep each run fast

capture::DaemonConfig make_config() {
  capture::DaemonConfig c;
  c.runtime_dir = fuzz::scratch_dir() / "run";
  c.sessions_dir = fuzz::scratch_dir() / "sessions";
  c.rig_config = sim::sim_rig_config(
      {{"scene", "patchwork"},
       {"samples_per_axis", 1},
       {"camera", {{"width", 32}, {"height", 24}, {"fx", 40}, {"fy", 40}, {"cx", 15.5}, {"cy", 11.5}}}});
  c.make_rig = [](const json& config) -> Result<rig::Rig> {
    const json camera = config.is_object() && config.contains("sim") && config["sim"].is_object()
                            ? config["sim"].value("camera", json::object())
                            : json::object();
    if (camera.is_object()) {
      const json w = camera.value("width", json(640)), h = camera.value("height", json(480));
      if (w.is_number() && h.is_number() && w.get<double>() * h.get<double>() > kMaxCameraPixels)
        return make_error(ErrorCode::kUnsupported, "fuzz: camera too large for a fuzz run");
    }
    if (config.is_object() && config.contains("sim") && config["sim"].is_object() &&
        config["sim"].value("time_scale", json(0)) != json(0))
      return make_error(ErrorCode::kUnsupported, "fuzz: real-time motion would make runs slow");
    rig::BackendRegistry registry;
    sim::register_backends(registry);
    return registry.make_rig(config);
  };
  c.capture.disk_reserve_bytes = 0;
  return c;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const capture::DaemonConfig config = make_config();
  std::filesystem::create_directories(config.sessions_dir);
  {
    capture::SessionRunner runner(config, [] {});
    capture::Protocol protocol(config, runner);
    std::string_view input(reinterpret_cast<const char*>(data), size);
    for (int n = 0; n < kMaxLines && !input.empty(); ++n) {
      const size_t end = input.find('\n');
      const std::string line(input.substr(0, end));
      input = end == std::string_view::npos ? std::string_view() : input.substr(end + 1);
      if (line.size() > config.max_line_bytes) continue;  // the server answers those itself (too_long)
      bool subscribed = false;
      std::optional<json> reply = protocol.answer(line, subscribed);
      // A started home/move is answered when the stage stops (the simulated one takes milliseconds).
      for (int wait_ms = 0; !reply && wait_ms < 10000; ++wait_ms) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        reply = protocol.take_deferred_reply();
      }
      if (!reply || !reply->is_object() || !reply->contains("ok") || !(*reply)["ok"].is_boolean()) std::abort();
      (void)runner.take_events();
    }
    runner.shutdown();
  }
  std::error_code ec;
  std::filesystem::remove_all(config.sessions_dir, ec);
  return 0;
}

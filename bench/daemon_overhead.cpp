// Daemon overhead per frame: an in-process vdrigd runs a session over its socket on the simulator with a small
// camera; every device call is timed by a wrapper, and the overhead is (session wall time - time inside device
// calls) / frames. It covers everything vdrigd adds: PNG encoding, the frame file and its fsync, the per-view commit
// (one folder fsync, one journal append + fsync for the whole bracket), the progress events and the socket.
// Target: < 5 ms per frame.
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>

#include "vdrig/capture/daemon.hpp"
#include "vdrig/sim/sim_rig.hpp"

using namespace vdrig;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {
using Clock = std::chrono::steady_clock;
std::atomic<int64_t> g_device_ns{0};

struct Timer {
  Clock::time_point t0 = Clock::now();
  ~Timer() { g_device_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count(); }
};

class TimedStage : public rig::PanTiltStage {
 public:
  explicit TimedStage(std::unique_ptr<rig::PanTiltStage> s) : s_(std::move(s)) {}
  std::string backend() const override { return s_->backend(); }
  rig::StageSpec spec() const override { return s_->spec(); }
  Status home() override {
    Timer t;
    return s_->home();
  }
  Status move_to(const PanTilt& p) override {
    Timer t;
    return s_->move_to(p);
  }
  Result<PanTilt> position() override {
    Timer t;
    return s_->position();
  }
  Status stop() override { return s_->stop(); }
  std::unique_ptr<rig::PanTiltStage> s_;
};

class TimedCamera : public rig::Camera {
 public:
  explicit TimedCamera(std::unique_ptr<rig::Camera> c) : c_(std::move(c)) {}
  std::string backend() const override { return c_->backend(); }
  Result<rig::CameraInfo> info() override {
    Timer t;
    return c_->info();
  }
  Status set_exposure(double e, double g) override {
    Timer t;
    return c_->set_exposure(e, g);
  }
  Result<Frame> capture() override {
    Timer t;
    return c_->capture();
  }
  std::unique_ptr<rig::Camera> c_;
};

std::string read_line(int fd, std::string& buf) {
  while (true) {
    const size_t pos = buf.find('\n');
    if (pos != std::string::npos) {
      std::string l = buf.substr(0, pos);
      buf.erase(0, pos + 1);
      return l;
    }
    char tmp[4096];
    const ssize_t n = ::recv(fd, tmp, sizeof tmp, 0);
    if (n <= 0) return {};
    buf.append(tmp, static_cast<size_t>(n));
  }
}
}  // namespace

int main() {
  const fs::path root = fs::temp_directory_path() / ("vdrig_bench_daemon_" + std::to_string(::getpid()));
  fs::remove_all(root);
  capture::DaemonConfig config;
  config.runtime_dir = root / "run";
  config.sessions_dir = root / "sessions";
  config.rig_config = sim::sim_rig_config(
      {{"samples_per_axis", 1},
       {"camera", {{"width", 320}, {"height", 240}, {"fx", 400}, {"fy", 400}, {"cx", 159.5}, {"cy", 119.5}}}});
  config.capture.disk_reserve_bytes = 0;
  config.make_rig = [](const json& rc) -> Result<rig::Rig> {
    rig::BackendRegistry registry;
    sim::register_backends(registry);
    auto r = registry.make_rig(rc);
    if (!r) return r;
    rig::Rig timed;
    timed.stage = std::make_unique<TimedStage>(std::move(r->stage));
    timed.camera = std::make_unique<TimedCamera>(std::move(r->camera));
    timed.light = std::move(r->light);
    return timed;
  };
  capture::Daemon daemon(config);
  if (const Status s = daemon.start(); !s) {
    std::fprintf(stderr, "%s\n", s.describe().c_str());
    return 1;
  }
  Status loop;
  std::thread t([&] { loop = daemon.run(); });
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strcpy(addr.sun_path, daemon.socket_path().c_str());
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) return 1;
  std::string buf;
  auto send = [&](const json& j) {
    const std::string l = j.dump() + "\n";
    return ::send(fd, l.data(), l.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(l.size());
  };
  send({{"cmd", "subscribe"}});
  read_line(fd, buf);
  // The clock starts at the first progress event: planning (route search, bounded by its time budget) and
  // session creation are once per session, not per frame.
  send({{"cmd", "start"}, {"session", "bench"}, {"scheme", "spiral:100:6@80"}, {"bracket", "fixed:0.5,0.25,0.125"}});
  Clock::time_point t0;
  bool started = false;
  int frames = 0;
  std::string state;
  while (state.empty()) {
    const std::string line = read_line(fd, buf);
    if (line.empty()) break;
    const json ev = json::parse(line, nullptr, false);
    if (ev.is_discarded()) continue;
    if (!started && ev.value("event", "") == "progress" && !ev.value("view_finished", true)) {
      t0 = Clock::now();  // after the first frame: count the remaining ones
      g_device_ns = 0;
      started = true;
      continue;
    }
    if (ev.value("event", "") == "progress" && !ev.value("view_finished", true)) ++frames;
    if (ev.value("event", "") == "state" && ev.value("state", "") != "running") state = ev["state"];
  }
  const double wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const double device_s = g_device_ns.load() * 1e-9;
  ::close(fd);
  daemon.request_stop();
  t.join();
  fs::remove_all(root);
  if (state != "completed" || frames == 0) {
    std::fprintf(stderr, "session did not complete (%s)\n", state.c_str());
    return 1;
  }
  const double overhead_ms = (wall_s - device_s) / frames * 1e3;
  std::printf("daemon overhead: %d frames (320x240), wall %.3f s, in simulated devices %.3f s\n", frames, wall_s,
              device_s);
  std::printf("daemon overhead per frame: %.2f ms (target < 5 ms) %s\n", overhead_ms, overhead_ms < 5 ? "OK" : "OVER");
  return 0;
}

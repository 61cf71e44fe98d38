// vdrigd under a crowd: N clients (200 by default) connect at once, each asks `status` and waits up to 10 s for the
// reply. Prints how many were answered, how many were refused with "too many clients" (an immediate, explicit reply)
// and how many got nothing, with the latency percentiles of the answers (docs/protocol.md, "Connections").
// Before the listen backlog was the system's and the limits per uid existed, 124-127 of 200 got no reply in 10 s.
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "vdrig/capture/daemon.hpp"
#include "vdrig/sim/sim_rig.hpp"

using namespace vdrig;
using nlohmann::json;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

/// One client: connect, send `status`, read one line within 10 s. Returns the line ("" when none came).
std::string ask_status(const fs::path& socket_path) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, socket_path.c_str(), sizeof addr.sun_path - 1);
  std::string line;
  if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) {
    const std::string req = "{\"cmd\":\"status\"}\n";
    (void)::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
    const auto deadline = Clock::now() + std::chrono::seconds(10);
    std::string buf;
    while (Clock::now() < deadline && buf.find('\n') == std::string::npos) {
      pollfd p{fd, POLLIN, 0};
      const int left =
          static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count());
      if (::poll(&p, 1, std::max(1, left)) <= 0) break;
      char tmp[4096];
      const ssize_t n = ::recv(fd, tmp, sizeof tmp, 0);
      if (n <= 0) break;
      buf.append(tmp, static_cast<size_t>(n));
    }
    if (buf.find('\n') != std::string::npos) line = buf.substr(0, buf.find('\n'));
  }
  if (fd >= 0) ::close(fd);
  return line;
}

}  // namespace

int main(int argc, char** argv) {
  const int clients = argc > 1 ? std::atoi(argv[1]) : 200;
  const fs::path root = fs::temp_directory_path() / ("vdrig_bench_clients_" + std::to_string(::getpid()));
  capture::DaemonConfig config;
  config.runtime_dir = root / "run";
  config.sessions_dir = root / "sessions";
  config.rig_config = sim::sim_rig_config({{"scene", "patchwork"}, {"camera", {{"width", 64}, {"height", 48}}}});
  config.make_rig = [](const json& rc) {
    rig::BackendRegistry registry;
    sim::register_backends(registry);
    return registry.make_rig(rc);
  };
  capture::Daemon daemon(config);
  if (const Status s = daemon.start(); !s) {
    std::fprintf(stderr, "%s\n", s.describe().c_str());
    return 1;
  }
  std::thread loop([&] { (void)daemon.run(); });

  std::vector<double> latency_ms;
  int answered = 0, refused = 0, silent = 0;
  std::mutex m;
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i)
    threads.emplace_back([&] {
      while (!go.load()) std::this_thread::yield();
      const auto t0 = Clock::now();
      const std::string line = ask_status(daemon.socket_path());
      const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
      const json reply = json::parse(line, nullptr, false);
      std::lock_guard lock(m);
      if (line.empty() || reply.is_discarded()) {
        ++silent;
      } else if (reply.value("ok", false)) {
        ++answered;
        latency_ms.push_back(ms);
      } else {
        ++refused;
      }
    });
  go = true;
  for (auto& t : threads) t.join();
  daemon.request_stop();
  loop.join();
  fs::remove_all(root);

  std::sort(latency_ms.begin(), latency_ms.end());
  auto pct = [&](double q) {
    return latency_ms.empty() ? 0.0
                              : latency_ms[std::min(latency_ms.size() - 1, static_cast<size_t>(q * latency_ms.size()))];
  };
  std::printf(
      "%d clients asking status at once: %d answered (latency p50 %.1f ms, p99 %.1f ms, max %.1f ms), %d refused "
      "with \"too many clients\", %d without a reply in 10 s\n",
      clients, answered, pct(0.5), pct(0.99), latency_ms.empty() ? 0.0 : latency_ms.back(), refused, silent);
  return silent == 0 ? 0 : 1;
}

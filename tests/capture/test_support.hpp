// Helpers shared by the capture tests: the small simulated rig and a line-based client for vdrigd's socket
// (docs/protocol.md). Temporary folders come from vdrig/test/temp_dir.hpp, as in every module's tests.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "vdrig/capture/daemon_client.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::capture::testing {

/// The simulator at 160x120 with one sample per pixel axis: fast enough for sessions of a hundred views.
/// A manifest of `views` planned views (view i looks along +z) with a fixed one-exposure bracket: what the
/// session-file tests need, without a rig.
inline Manifest manifest_with_views(int views) {
  Manifest m;
  m.scheme = "test";
  m.bracket = "fixed:0.01";
  m.exposures_s = {0.01};
  for (int i = 0; i < views; ++i) m.views.push_back({i, Vec3d::UnitZ(), {}});
  return m;
}

inline nlohmann::json small_sim_config() {
  return sim::sim_rig_config(
      {{"scene", "patchwork"},
       {"samples_per_axis", 1},
       {"camera", {{"width", 160}, {"height", 120}, {"fx", 200}, {"fy", 200}, {"cx", 79.5}, {"cy", 59.5}}}});
}

inline Result<rig::Rig> make_sim_rig(const nlohmann::json& config) {
  rig::BackendRegistry registry;
  sim::register_backends(registry);
  return registry.make_rig(config);
}

// The socket helpers below are the test-friendly face of vdrig/capture/daemon_client.hpp (the one client of
// vdrigd that `vdrig session` and `vdrig serve` use too): raw descriptors the tests own, so that they can also send
// what no well-behaved client sends.

/// Connects to a Unix stream socket; -1 on failure.
inline int connect_unix(const std::filesystem::path& socket_path) {
  auto fd = ::vdrig::capture::connect_unix(socket_path);
  return fd ? fd.value() : -1;
}

inline bool send_all(int fd, const std::string& bytes) { return ::vdrig::capture::send_all(fd, bytes).is_ok(); }

/// Reads one line; nullopt when the connection closed (or nothing came within the timeout).
inline std::optional<std::string> read_line(int fd, std::string& buffer, int timeout_ms = 5000) {
  auto line = ::vdrig::capture::read_line(fd, buffer, timeout_ms);
  if (!line) return std::nullopt;
  return std::move(line).value();
}

/// Sends a request and returns its reply, skipping pushed events; {"closed": true} when the connection ended and
/// {"unparseable": LINE} for a reply that is not JSON.
inline nlohmann::json request(int fd, std::string& buffer, const nlohmann::json& req, int timeout_ms = 5000) {
  if (!send_all(fd, req.dump() + "\n")) return nlohmann::json{{"closed", true}};
  while (true) {
    auto line = read_line(fd, buffer, timeout_ms);
    if (!line) return nlohmann::json{{"closed", true}};
    nlohmann::json j = nlohmann::json::parse(*line, nullptr, false);
    if (j.is_discarded()) return nlohmann::json{{"unparseable", *line}};
    if (!j.contains("event")) return j;
  }
}

/// The built executables the process-level tests run: `env` when set (to run the tests against another build),
/// else the path CMake compiled in (VDRIG_CLI_PATH / VDRIG_VDRIGD_PATH), else "".
inline std::string executable(const char* env, const char* built) {
  const char* e = std::getenv(env);
  return e && *e ? e : built;
}
inline std::string vdrig_cli() {
#ifdef VDRIG_CLI_PATH
  return executable("VDRIG_TEST_CLI", VDRIG_CLI_PATH);
#else
  return executable("VDRIG_TEST_CLI", "");
#endif
}
inline std::string vdrigd_exe() {
#ifdef VDRIG_VDRIGD_PATH
  return executable("VDRIG_TEST_VDRIGD", VDRIG_VDRIGD_PATH);
#else
  return executable("VDRIG_TEST_VDRIGD", "");
#endif
}

// Child processes: vdrig::test::run_process (vdrig/test/process.hpp), as in every module's tests.
using vdrig::test::ProcessRun;
using vdrig::test::run_process;

inline void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

}  // namespace vdrig::capture::testing

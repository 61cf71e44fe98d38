// The independent Modbus TCP drive peer (tests/rig/modbus_drive_peer.py, Debian's python3-pymodbus) as a child
// process of a test: started on a free port it reports itself, driven through its stdin (fault commands, see the
// script's docstring), killed when the object goes away.
#pragma once

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "vdrig/test/build_paths.hpp"

namespace vdrig::test {

/// Debian's interpreter, not whatever `python3` is first on PATH (a pyenv one would lack python3-pymodbus).
inline constexpr const char* kSystemPython = "/usr/bin/python3";

/// The peer script in the source tree.
inline std::filesystem::path modbus_peer_script() {
  return std::filesystem::path(VDRIG_SOURCE_DIR) / "tests" / "rig" / "modbus_drive_peer.py";
}

/// Empty when the peer can run here; otherwise why not (the test then skips).
inline std::string modbus_peer_unavailable() {
  if (::access(kSystemPython, X_OK) != 0) return std::string(kSystemPython) + " not found";
  const std::string probe = std::string(kSystemPython) + " -c 'import pymodbus.server' >/dev/null 2>&1";
  if (std::system(probe.c_str()) != 0) return "python3-pymodbus is not installed (scripts/setup installs it)";
  return "";
}

class ModbusPeer {
 public:
  /// Starts the peer with `extra_args` (e.g. "--word-order low-first") and waits (up to 10 s) until it listens.
  explicit ModbusPeer(const std::string& extra_args = "") {
    ::signal(SIGPIPE, SIG_IGN);  // a peer that died must fail the test, not kill it
    int to_child[2], from_child[2];
    if (::pipe(to_child) != 0 || ::pipe(from_child) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(to_child[0], 0);
      ::dup2(from_child[1], 1);
      ::close(to_child[1]);
      ::close(from_child[0]);
      const std::string cmd =
          "exec " + std::string(kSystemPython) + " " + modbus_peer_script().string() + " " + extra_args;
      ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(to_child[0]);
    ::close(from_child[1]);
    in_ = to_child[1];
    out_ = from_child[0];
    if (auto line = expect("LISTENING", 10.0)) port_ = std::stoi(line->substr(10));
  }
  ~ModbusPeer() {
    if (in_ >= 0) ::close(in_);
    if (out_ >= 0) ::close(out_);
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
  }
  ModbusPeer(const ModbusPeer&) = delete;
  ModbusPeer& operator=(const ModbusPeer&) = delete;

  /// The TCP port it listens on; 0 when it did not start.
  int port() const { return port_; }

  /// Sends one command line and waits for its "OK ..." acknowledgement; false on an error or no answer.
  bool command(const std::string& line) {
    const std::string text = line + "\n";
    if (::write(in_, text.data(), text.size()) != static_cast<ssize_t>(text.size())) return false;
    return expect("OK " + line, 5.0).has_value();
  }

  /// The peer's view of drive `unit`: "STATE <unit> moving=0|1 position=N target=N fault=N".
  std::string query(int unit) {
    const std::string text = "query " + std::to_string(unit) + "\n";
    if (::write(in_, text.data(), text.size()) != static_cast<ssize_t>(text.size())) return "";
    return expect("STATE " + std::to_string(unit), 5.0).value_or("");
  }
  bool moving(int unit) { return query(unit).find("moving=1") != std::string::npos; }

  /// Reads lines until one starts with `prefix` (returned) or `timeout_s` passes.
  std::optional<std::string> expect(const std::string& prefix, double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
      for (size_t nl; (nl = buffer_.find('\n')) != std::string::npos;) {
        std::string line = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        if (line.compare(0, prefix.size(), prefix) == 0) return line;
      }
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0 || out_ < 0) return std::nullopt;
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char chunk[512];
      const ssize_t n = ::read(out_, chunk, sizeof chunk);
      if (n <= 0) return std::nullopt;  // the peer died
      buffer_.append(chunk, static_cast<size_t>(n));
    }
  }

 private:
  pid_t pid_ = -1;
  int in_ = -1, out_ = -1;
  int port_ = 0;
  std::string buffer_;
};

}  // namespace vdrig::test

// Crash-safety tests' SIGKILL at a random moment of real work: a forked child runs the work while the parent watches
// a file the work appends to (a session's journal), and kills the child once the file has grown to a target size
// (plus a random further delay), so that the kill lands inside a write as often as between two.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <system_error>
#include <thread>

namespace vdrig::test {

/// Forks; the child runs `work()` and exits 0 if it returned true (or a Status / Result that converts to true), else
/// 3. The parent polls `file` every 200 us: once it is `target_bytes` long, or `timeout` has passed, it sleeps
/// `extra_us()` microseconds and SIGKILLs the child, unless the child has exited first. Returns the child's wait
/// status (WIFSIGNALED: killed mid-work), nullopt when fork failed. `extra_us` is called only when a kill follows.
template <typename Work, typename ExtraUs>
std::optional<int> kill_when_grown(Work&& work, const std::filesystem::path& file, std::uintmax_t target_bytes,
                                   ExtraUs&& extra_us, std::chrono::seconds timeout) {
  const pid_t pid = ::fork();
  if (pid < 0) return std::nullopt;
  if (pid == 0) ::_exit(work() ? 0 : 3);
  int status = 0;
  bool exited = false;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    std::error_code ec;
    if (std::filesystem::file_size(file, ec) >= target_bytes) break;
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      exited = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  if (!exited) {
    std::this_thread::sleep_for(std::chrono::microseconds(extra_us()));
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
  }
  return status;
}

}  // namespace vdrig::test

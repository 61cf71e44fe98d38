// Running a program from a test (the built vdrig or vdrigd, mpirun, ffprobe, chromium) the same way in every
// module's tests: with a time limit, stdin from /dev/null, stdout and stderr captured (never a terminal), and the exit
// code as a number the test can compare.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "vdrig/test/build_paths.hpp"

namespace vdrig::test {

/// What a finished (or killed) child process left.
struct ProcessRun {
  /// The program's exit status (0..255); 128 + N when signal N killed it; 124 when the time limit killed it (as
  /// timeout(1) says, so "a hang" reads the same as before); 127 when the program could not be started.
  int exit_code = -1;
  int signal = 0;          ///< the signal that killed it (0: it exited, or the time limit killed it)
  bool timed_out = false;  ///< killed by the time limit (exit_code is then 124)
  std::string out;         ///< stdout (and stderr with ProcessOptions::merge_stderr)
  std::string err;         ///< stderr; empty with ProcessOptions::merge_stderr
  double wall_s = 0;       ///< from start to exit (or kill)
};

struct ProcessOptions {
  double timeout_s = 120;     ///< then the child's whole process group gets SIGKILL
  bool merge_stderr = false;  ///< stderr into `out` too, interleaved as written (`2>&1`)
};

/// `text` as one word for /bin/sh, in single quotes (a ' inside becomes '\'').
inline std::string shell_quote(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

/// Runs `argv` (argv[0] is the executable's path, not looked up on PATH) in a process group of its own, with stdin
/// from /dev/null and stdout and stderr to files, and waits for it; after `options.timeout_s` the group (the program
/// and whatever it started) is killed. Blocks; the caller's stdout and stderr are untouched.
inline ProcessRun run_process(const std::vector<std::string>& argv, const ProcessOptions& options = {}) {
  static int counter = 0;  // several runs in one test process get files of their own
  const std::filesystem::path base = std::filesystem::temp_directory_path() /
                                     ("vdrig_proc_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  const std::string out_file = base.string() + ".out", err_file = base.string() + ".err";
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    const int in = ::open("/dev/null", O_RDONLY);
    const int out = ::open(out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = options.merge_stderr ? out : ::open(err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(in, 0);
    ::dup2(out, 1);
    ::dup2(err, 2);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  ProcessRun r;
  int status = 0;
  const auto deadline = start + std::chrono::duration<double>(options.timeout_s);
  while (true) {
    if (::waitpid(pid, &status, WNOHANG) == pid) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(-pid, SIGKILL);  // the group: a shell's or mpirun's children too
      ::kill(pid, SIGKILL);   // in case the child had not yet made its group
      ::waitpid(pid, &status, 0);
      r.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (r.timed_out)
    r.exit_code = 124;
  else if (WIFEXITED(status))
    r.exit_code = WEXITSTATUS(status);
  else if (WIFSIGNALED(status))
    r.exit_code = 128 + (r.signal = WTERMSIG(status));
  auto slurp = [](const std::string& f) {
    std::ifstream in(f, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  r.out = slurp(out_file);
  if (!options.merge_stderr) r.err = slurp(err_file);
  std::error_code ignored;
  std::filesystem::remove(out_file, ignored);
  std::filesystem::remove(err_file, ignored);
  return r;
}

/// `command` as /bin/sh -c runs it (the caller quotes its words, e.g. with shell_quote), as run_process runs a
/// program: the shell's exit status is the last command's.
inline ProcessRun run_shell(const std::string& command, const ProcessOptions& options = {}) {
  return run_process({"/bin/sh", "-c", command}, options);
}

#ifdef VDRIG_CLI_PATH
/// The built `vdrig` (VDRIG_CLI_PATH, which tests/CMakeLists.txt defines for the tests that run it) with `args`,
/// a shell fragment (quote paths with shell_quote), through run_shell.
inline ProcessRun run_vdrig(const std::string& args, const ProcessOptions& options = {}) {
  return run_shell(shell_quote(VDRIG_CLI_PATH) + " " + args, options);
}
#endif

}  // namespace vdrig::test

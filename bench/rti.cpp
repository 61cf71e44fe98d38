// bench_rti: RTI jobs end to end as a user runs them, beside relight-cli (the peer, built by scripts/build_relight)
// when it is present. Two synthetic JPEG stacks with their .lp (tests/rti/synthetic_stack.hpp; written first and
// not timed): 289 and 60 lights at 256x256. Per stack: hsh:3 to .rti (relight-cli -b hsh -p 27), ptm:rgb to .ptm
// (-b ptm -p 18) and relight's default basis rbf with 9 planes to a relight folder (-b rbf -p 9). vdrig runs as the
// `vdrig` executable, one process per step (import + fit + export, or import + rbf); each step's wall time, CPU time
// (user + system) and peak RSS come from wait4 on the child. docs/rti.md has the figures.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "synthetic_stack.hpp"

namespace {

namespace fs = std::filesystem;

struct Run {
  double wall_s = 0;
  double cpu_s = 0;  // user + system: what the wall time would be on a quiet machine with one core
  double peak_mb = 0;
  int status = -1;
};

Run run(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);  // the steps' progress lines would bury the table
    ::dup2(null, 1);
    ::execv(argv[0], argv.data());
    std::_Exit(127);
  }
  int status = 0;
  rusage ru{};
  ::wait4(pid, &status, 0, &ru);
  Run r;
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.peak_mb = ru.ru_maxrss / 1024.0;
  r.cpu_s = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// relight-cli (the peer, scripts/build_relight): $VDRIG_RELIGHT_CLI, or where the script builds it.
std::string relight_cli() {
  if (const char* env = std::getenv("VDRIG_RELIGHT_CLI"); env && *env) return env;
  return (fs::path(VDRIG_SOURCE_DIR) / "build/peers/relight/build/relight-cli/relight-cli").string();
}

void print_row(const char* stack, const char* tool, const char* job, const std::vector<Run>& steps) {
  double wall = 0, cpu = 0, peak = 0;
  std::string split;
  for (const Run& r : steps) {
    wall += r.wall_s;
    cpu += r.cpu_s;
    peak = std::max(peak, r.peak_mb);
    char part[32];
    std::snprintf(part, sizeof part, "%s%.2f", split.empty() ? "" : " + ", r.wall_s);
    split += part;
  }
  std::printf("%-10s %-12s %-16s %9.2f %9.2f %12.1f   %s\n", stack, tool, job, wall, cpu, peak, split.c_str());
}

}  // namespace

int main() {
  const std::string vdrig = VDRIG_CLI_PATH;
  const std::string relight = relight_cli();
  const bool have_relight = fs::is_regular_file(relight);
  if (!have_relight)
    std::printf(
        "relight-cli (the peer) is not built: its rows are skipped (scripts/build_relight, or set "
        "VDRIG_RELIGHT_CLI; looked for %s)\n",
        relight.c_str());
  const fs::path dir = fs::temp_directory_path() / ("vdrig_bench_rti_" + std::to_string(::getpid()));
  bool ok = true;
  std::printf("%-10s %-12s %-16s %9s %9s %12s   %s\n", "stack", "tool", "job", "wall s", "CPU s", "peak RSS MB",
              "wall per step (vdrig: import + fit + export)");
  struct Stack {
    int lights, size;
  };
  for (const Stack st : {Stack{289, 256}, Stack{60, 256}}) {
    char name[32];
    std::snprintf(name, sizeof name, "%dx%d^2", st.lights, st.size);
    const fs::path stack = dir / name;
    fs::create_directories(stack);
    vdrig::test::write_synthetic_stack(stack, st.size, st.size, st.lights, ".jpg");  // not timed
    const std::string obs = (dir / "stack.vdobs").string();
    auto vdrig_import = [&] {
      return run({vdrig, "--log-level", "warn", "rti", "import", stack.string(), "--out", obs, "--response", "linear"});
    };
    struct Job {
      const char* model;
      const char* format;
      const char* out;
      std::vector<std::string> relight_args;
    };
    for (const Job& job : {Job{"hsh:3", "rti", "out.rti", {"-b", "hsh", "-p", "27"}},
                           Job{"ptm:rgb", "ptm", "out.ptm", {"-b", "ptm", "-p", "18"}},
                           Job{"rbf:9", "relight", "rbf", {"-b", "rbf", "-p", "9"}}}) {
      const std::string out = (dir / job.out).string();
      std::vector<Run> steps = {vdrig_import()};
      if (std::string(job.model) == "rbf:9") {
        steps.push_back(run({vdrig, "--log-level", "warn", "rti", "rbf", obs, "--planes", "9", "--out", out}));
      } else {
        const std::string map = (dir / (std::string(job.format) + ".exr")).string();
        steps.push_back(run({vdrig, "--log-level", "warn", "rti", "fit", obs, "--model", job.model, "--out", map}));
        steps.push_back(
            run({vdrig, "--log-level", "warn", "rti", "export", map, "--format", job.format, "--out", out}));
      }
      for (const Run& r : steps) ok = ok && r.status == 0;
      print_row(name, "vdrig", job.model, steps);
      fs::remove(obs);
      fs::remove_all(out);
      if (have_relight) {
        // -I srgb: relight-cli fits the codes as they are, as vdrig's --response linear import does.
        std::vector<std::string> args = {relight};
        args.insert(args.end(), job.relight_args.begin(), job.relight_args.end());
        args.insert(args.end(), {"-I", "srgb", stack.string(), out});
        const Run r = run(args);
        if (r.status != 0) std::printf("relight-cli %s exited with %d\n", job.model, r.status);
        print_row(name, "relight-cli", job.model, {r});
        fs::remove_all(out);
      }
    }
    fs::remove_all(stack);
  }
  fs::remove_all(dir);
  if (!ok) std::printf("a vdrig step failed\n");
  return ok ? 0 : 1;
}

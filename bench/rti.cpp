// bench_rti: an RTI job end to end as a user runs it, vdrig beside relight-cli on the same stacks, interleaved.
// Synthetic JPEG stacks with their .lp (tests/rti/synthetic_stack.hpp; written first, not timed): 289 lights at
// 256x256 and 60 at 256x256 (and 289 at 1024x1024 with --large). Each job is one command, as a user runs it, both
// tools fitting the codes as they are (vdrig's default; relight-cli's -I srgb, docs/rti.md "Colour"):
//   vdrig rti fit STACK --model ptm:rgb --out out.ptm      relight-cli -I srgb -b ptm -p 18 STACK out.ptm
//   vdrig rti fit STACK --model hsh:3 --out out.rti        relight-cli -I srgb -b hsh -p 27 STACK out.rti
//   vdrig rti rbf STACK --planes 9 --out out/              relight-cli -I srgb -b rbf -p 9 STACK out/
// and, with --three-step, vdrig's path through an observation map for reference (rti import + rti fit of the map +
// rti export; rti import + rti rbf of the map). Prints the median wall and CPU seconds (user + system of the child,
// wait4) over --repeat runs, the largest peak RSS, and relight / vdrig ratios. relight-cli is found as the tests
// find it ($VDRIG_RELIGHT_CLI or scripts/build_relight's build/peers/relight/...); without it only vdrig's figures
// are printed. `--write-stacks DIR` writes the stacks into DIR and exits (for perf). docs/rti.md has the results.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "synthetic_stack.hpp"
#include "vdrig/test/build_paths.hpp"

namespace {

namespace fs = std::filesystem;

struct Run {
  double wall_s = 0;
  double cpu_s = 0;  // user + system: steadier than wall on a shared machine
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
    const int null = ::open("/dev/null", O_WRONLY);  // progress lines would bury the table
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(argv[0], argv.data());
    std::_Exit(127);
  }
  int status = 0;
  rusage ru{};
  ::wait4(pid, &status, 0, &ru);
  Run r;
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.peak_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;
  r.cpu_s = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// Several steps of one job as one run: times add up, peak RSS is the largest.
Run run_steps(const std::vector<std::vector<std::string>>& steps) {
  Run total;
  total.status = 0;
  for (const auto& step : steps) {
    const Run r = run(step);
    total.wall_s += r.wall_s;
    total.cpu_s += r.cpu_s;
    total.peak_mb = std::max(total.peak_mb, r.peak_mb);
    if (r.status != 0) total.status = r.status;
  }
  return total;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

std::string find_relight_cli() {
  if (const char* env = std::getenv("VDRIG_RELIGHT_CLI"); env && ::access(env, X_OK) == 0) return env;
  const fs::path built =
      fs::path(VDRIG_SOURCE_DIR) / "build" / "peers" / "relight" / "build" / "relight-cli" / "relight-cli";
  return ::access(built.c_str(), X_OK) == 0 ? built.string() : "";
}

struct Summary {
  double wall_s = 0, cpu_s = 0, peak_mb = 0;
  bool ok = true;
};

Summary summarise(const std::vector<Run>& runs) {
  Summary s;
  std::vector<double> wall, cpu;
  for (const Run& r : runs) {
    wall.push_back(r.wall_s);
    cpu.push_back(r.cpu_s);
    s.peak_mb = std::max(s.peak_mb, r.peak_mb);
    s.ok = s.ok && r.status == 0;
  }
  s.wall_s = median(wall);
  s.cpu_s = median(cpu);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  bool large = false, three_step = false;
  int repeat = 3;
  std::string write_stacks;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--large") == 0) large = true;
    if (std::strcmp(argv[i], "--three-step") == 0) three_step = true;
    if (std::strcmp(argv[i], "--repeat") == 0 && i + 1 < argc) repeat = std::max(1, std::atoi(argv[++i]));
    if (std::strcmp(argv[i], "--write-stacks") == 0 && i + 1 < argc) write_stacks = argv[++i];
  }
  const std::string vdrig = VDRIG_CLI_PATH;
  const std::string relight = find_relight_cli();
  if (relight.empty() && write_stacks.empty())
    std::printf("relight-cli not found (scripts/build_relight, or VDRIG_RELIGHT_CLI): vdrig's figures only\n");
  const fs::path dir = fs::temp_directory_path() / ("vdrig_bench_rti_" + std::to_string(::getpid()));

  struct Case {
    int lights, side;
  };
  std::vector<Case> cases = {{289, 256}, {60, 256}};
  if (large) cases.push_back({289, 1024});
  if (!write_stacks.empty()) {
    for (const Case& c : cases) {
      const fs::path stack =
          fs::path(write_stacks) / ("stack_" + std::to_string(c.lights) + "x" + std::to_string(c.side));
      fs::create_directories(stack);
      vdrig::test::write_synthetic_stack(stack, c.side, c.side, c.lights, ".jpg");
      std::printf("%s\n", stack.c_str());
    }
    return 0;
  }
  bool ok = true;
  std::printf("%-12s %-8s %-22s %8s %8s %9s\n", "stack", "basis", "tool", "wall s", "CPU s", "peak MB");
  for (const Case& c : cases) {
    const fs::path stack = dir / "stack";
    fs::remove_all(dir);
    fs::create_directories(stack);
    vdrig::test::write_synthetic_stack(stack, c.side, c.side, c.lights, ".jpg");
    char label[32];
    std::snprintf(label, sizeof label, "%d x %d²", c.lights, c.side);
    struct Job {
      const char* basis;
      const char* model;  // vdrig rti fit --model; nullptr: vdrig rti rbf
      const char* relight_basis;
      const char* relight_planes;
      const char* format;  // ptm, rti; relight: a folder
    };
    for (const Job job : {Job{"PTM-18", "ptm:rgb", "ptm", "18", "ptm"}, Job{"HSH-27", "hsh:3", "hsh", "27", "rti"},
                          Job{"RBF-9", nullptr, "rbf", "9", "relight"}}) {
      const bool rbf = job.model == nullptr;
      const std::string out = (dir / (std::string("out.") + job.format)).string();
      const std::string obs = (dir / "stack.vdobs").string(), map = (dir / "map.exr").string();
      std::vector<Run> one, three, peer;
      for (int r = 0; r < repeat; ++r) {  // interleaved, so that load changes hit every tool alike
        fs::remove_all(out);
        if (rbf)
          one.push_back(run({vdrig, "rti", "rbf", stack.string(), "--planes", job.relight_planes, "--out", out}));
        else
          one.push_back(run({vdrig, "rti", "fit", stack.string(), "--model", job.model, "--out", out}));
        fs::remove_all(out);
        if (!relight.empty())
          peer.push_back(
              run({relight, "-I", "srgb", "-b", job.relight_basis, "-p", job.relight_planes, stack.string(), out}));
        if (!three_step) continue;
        fs::remove_all(out);
        if (rbf)
          three.push_back(run_steps({{vdrig, "rti", "import", stack.string(), "--out", obs},
                                     {vdrig, "rti", "rbf", obs, "--planes", job.relight_planes, "--out", out}}));
        else
          three.push_back(run_steps({{vdrig, "rti", "import", stack.string(), "--out", obs},
                                     {vdrig, "rti", "fit", obs, "--model", job.model, "--out", map},
                                     {vdrig, "rti", "export", map, "--format", job.format, "--out", out}}));
      }
      const Summary a = summarise(one);
      ok = ok && a.ok;
      std::printf("%-12s %-8s %-22s %8.2f %8.2f %9.1f\n", label, job.basis,
                  rbf ? "vdrig rti rbf STACK" : "vdrig rti fit STACK", a.wall_s, a.cpu_s, a.peak_mb);
      if (three_step) {
        const Summary b = summarise(three);
        ok = ok && b.ok;
        std::printf("%-12s %-8s %-22s %8.2f %8.2f %9.1f\n", label, job.basis,
                    rbf ? "vdrig import+rbf" : "vdrig import+fit+export", b.wall_s, b.cpu_s, b.peak_mb);
      }
      if (!peer.empty()) {
        const Summary p = summarise(peer);
        std::printf("%-12s %-8s %-22s %8.2f %8.2f %9.1f%s\n", label, job.basis, "relight-cli", p.wall_s, p.cpu_s,
                    p.peak_mb, p.ok ? "" : "  (failed)");
        std::printf("%-12s %-8s %-22s %7.1fx %7.1fx %8.2fx\n", label, job.basis, "relight / vdrig", p.wall_s / a.wall_s,
                    p.cpu_s / a.cpu_s, p.peak_mb / a.peak_mb);
      }
      std::fflush(stdout);
    }
  }
  fs::remove_all(dir);
  if (!ok) std::printf("a vdrig run failed\n");
  return ok ? 0 : 1;
}

// bench_rti: an RTI job end to end as a user runs it: a 289-image 256x256 JPEG stack with its .lp (synthetic,
// written first and not timed) through `vdrig rti import`, `vdrig rti fit --model hsh:3` (27 coefficients) and
// `vdrig rti export --format rti`, and the same with ptm:rgb (18 coefficients) to .ptm. Prints each step's wall time
// and CPU time and peak RSS (getrusage of the child, wait4) and the fit's median leave-one-out error in 8-bit codes.
// docs/rti.md has the figures and relight-cli's on this machine class.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "synthetic_stack.hpp"
#include "vdrig/fitting/parameter_map.hpp"

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

double median_loo_codes(const fs::path& map_file) {
  auto map = vdrig::fitting::ParameterMap::read(map_file);
  if (!map) return -1;
  std::vector<float> v;
  for (int t = 0; t < map->texels_t(); ++t)
    for (int s = 0; s < map->texels_s(); ++s)
      v.push_back(255.0f * (map->at("loo.R", s, t) + map->at("loo.G", s, t) + map->at("loo.B", s, t)) / 3.0f);
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main() {
  const std::string vdrig = VDRIG_CLI_PATH;
  const fs::path dir = fs::temp_directory_path() / ("vdrig_bench_rti_" + std::to_string(::getpid()));
  fs::create_directories(dir / "stack");
  std::printf("writing a 289-image 256x256 JPEG stack to %s ...\n", dir.c_str());
  vdrig::test::write_synthetic_stack(dir / "stack", 256, 256, 289, ".jpg");
  const std::string obs = (dir / "stack.vdobs").string();

  struct Job {
    const char* model;
    const char* format;
    const char* out;
  };
  bool ok = true;
  std::printf("%-8s %-8s %9s %9s %9s %9s %9s %12s %14s\n", "model", "format", "import s", "fit s", "export s",
              "total s", "CPU s", "peak RSS MB", "median LOO");
  for (const Job job : {Job{"hsh:3", "rti", "out.rti"}, Job{"ptm:rgb", "ptm", "out.ptm"}}) {
    const std::string map = (dir / (std::string(job.format) + ".exr")).string();
    const Run a = run({vdrig, "--log-level", "warn", "rti", "import", (dir / "stack").string(), "--out", obs,
                       "--response", "linear"});
    const Run b = run({vdrig, "--log-level", "warn", "rti", "fit", obs, "--model", job.model, "--out", map});
    const Run c = run({vdrig, "--log-level", "warn", "rti", "export", map, "--format", job.format, "--out",
                       (dir / job.out).string()});
    ok = ok && a.status == 0 && b.status == 0 && c.status == 0;
    std::printf("%-8s %-8s %9.2f %9.2f %9.2f %9.2f %9.2f %12.1f %9.3f codes\n", job.model, job.format, a.wall_s,
                b.wall_s, c.wall_s, a.wall_s + b.wall_s + c.wall_s, a.cpu_s + b.cpu_s + c.cpu_s,
                std::max({a.peak_mb, b.peak_mb, c.peak_mb}), median_loo_codes(map));
    fs::remove(obs);
  }
  fs::remove_all(dir);
  if (!ok) std::printf("a vdrig step failed\n");
  return ok ? 0 : 1;
}

#include "vdrig/probe/video.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace vdrig::probe {
namespace fs = std::filesystem;

fs::path find_on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  if (!path) return {};
  std::stringstream ss(path);
  std::string dir;
  while (std::getline(ss, dir, ':')) {
    if (dir.empty()) continue;
    const std::string candidate = dir + "/" + name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return {};
}

int run_program(const std::vector<std::string>& args) {
  if (args.empty()) return -1;
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, args[0].c_str(), nullptr, nullptr, argv.data(), environ) != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

Result<fs::path> encode_frames_mp4(const fs::path& frames_dir, double fps, const std::string& mp4_name) {
  if (!(fps > 0) || !std::isfinite(fps)) return make_error(ErrorCode::kInvalidArgument, "fps must be > 0");
  const fs::path ffmpeg = find_on_path("ffmpeg");
  if (ffmpeg.empty()) return make_error(ErrorCode::kNotFound, "ffmpeg not on PATH");
  const fs::path mp4 = frames_dir / mp4_name;
  char rate[32];
  std::snprintf(rate, sizeof rate, "%.6g", fps);
  const int rc = run_program({ffmpeg.string(), "-y", "-loglevel", "error", "-framerate", rate, "-i",
                              (frames_dir / "frame_%04d.png").string(), "-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2",
                              "-pix_fmt", "yuv420p", mp4.string()});
  if (rc != 0)
    return make_error(ErrorCode::kIo, "ffmpeg failed (exit " + std::to_string(rc) + ") writing " + mp4.string() +
                                          "; the PNG frames in " + frames_dir.string() + " are complete");
  return mp4;
}

}  // namespace vdrig::probe

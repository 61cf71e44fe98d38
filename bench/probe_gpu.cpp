// GPU fusion for a moving object (docs/probe.md, "GPU fusion"): per frame the probe fused at the object's position as
// a 6 x 128^2 cube on the GPU (probe_gl::GpuFusion), read back, shrunk 8x (16^2 faces) and turned into 64 soft lights
// (SH-9 + lights, soft_lights.hpp), over frames of bench_probe_temporal's path in its synthetic room (four 128 x 64
// probes with depth). Prints ms per frame for fusion, read-back, lights and the total, the frame rate, and the CPU
// fusion of the same cube (probe::fuse_cube) for comparison. Needs an OpenGL context (xvfb-run); exits 77 without one.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "synthetic_room.hpp"
#include "vdrig/gl/context.hpp"
#include "vdrig/probe/object_path.hpp"
#include "vdrig/probe/soft_lights.hpp"
#include "vdrig/probe_gl/gpu_fusion.hpp"

using namespace vdrig;
using namespace vdrig::probe;

namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// CPU time of the whole process (all threads, llvmpipe's included), ms.
double cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return 1e3 * (u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-3 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double load_average() {
  double l[1] = {0};
  return getloadavg(l, 1) == 1 ? l[0] : -1;
}

}  // namespace

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 120;
  const int size = argc > 2 ? std::atoi(argv[2]) : 128;
  const int shrink = argc > 3 ? std::atoi(argv[3]) : 8;
  auto ctx = gl::Context::create(16, 16, false);
  if (!ctx) {
    std::fprintf(stderr, "no OpenGL context: %s\n", ctx.error().message.c_str());
    return 77;
  }
  std::vector<Probe> probes;
  for (const Vec3d& p : testing::room_probe_positions()) probes.push_back(testing::render_room_probe(p, 64));
  ObjectPath path;
  for (int k = 0; k <= 24; ++k) {
    const double a = 2 * kPi * k / 24;
    path.keys.push_back({a, Vec3d(1300 * std::cos(a), 900 * std::sin(a), 1000 + 250 * std::sin(2 * a))});
  }
  const std::vector<Vec3d> positions = sample_path(path, frames);

  auto gpu = probe_gl::GpuFusion::create(probes, testing::kSyntheticRoom, size);
  if (!gpu) {
    std::fprintf(stderr, "%s\n", gpu.error().message.c_str());
    return 1;
  }
  std::printf("OpenGL renderer: %s\n", ctx.value()->renderer().c_str());
  // One frame to warm up (shader compilation happens lazily in some drivers).
  (void)gpu.value()->fuse(positions[0]);

  double fusion = 0, readback = 0, shrink_ms = 0, lights = 0, total = 0, worst_total = 0;
  const double cpu_start = cpu_ms();
  for (int f = 0; f < frames; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    if (!gpu.value()->render(positions[f]).is_ok()) return 1;
    gpu.value()->finish();
    const double t_fuse = ms_since(t0);
    const auto t1 = std::chrono::steady_clock::now();
    auto cube = gpu.value()->read_back();
    if (!cube) return 1;
    const double t_read = ms_since(t1);
    const auto t2 = std::chrono::steady_clock::now();
    const CubeMap small = downsample_cube(*cube, shrink);
    const double t_shrink = ms_since(t2);
    const auto t3 = std::chrono::steady_clock::now();
    const SoftLights soft = soft_lights(small);
    const double t_lights = ms_since(t3);
    if (soft.lights.size() != 64) return 1;
    const double t_total = ms_since(t0);
    fusion += t_fuse / frames;
    readback += t_read / frames;
    shrink_ms += t_shrink / frames;
    lights += t_lights / frames;
    total += t_total / frames;
    worst_total = std::max(worst_total, t_total);
  }
  const double cpu_per_frame = (cpu_ms() - cpu_start) / frames;
  std::printf("%d frames, 4 probes 128 x 64 -> cube 6 x %d^2, soft:64 on 6 x %d^2\n", frames, size, size / shrink);
  std::printf("  fusion (GPU draw)   %7.2f ms\n", fusion);
  std::printf("  read-back           %7.2f ms\n", readback);
  std::printf("  shrink %dx (CPU)     %7.2f ms\n", shrink, shrink_ms);
  std::printf("  soft:64 lights      %7.2f ms\n", lights);
  std::printf("  total               %7.2f ms per frame (%.1f frames/s; slowest frame %.2f ms)\n", total, 1e3 / total,
              worst_total);
  std::printf("  process CPU time    %7.2f ms per frame (all threads; the machine's load average was %.1f)\n",
              cpu_per_frame, load_average());

  // Pipelined, as `vdrig probe animate` could run it: frame f + 1 is fused on the GPU (llvmpipe's threads) while
  // the CPU turns frame f into lights.
  {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = cpu_ms();
    auto cube = gpu.value()->fuse(positions[0]);
    if (!cube) return 1;
    for (int f = 0; f < frames; ++f) {
      if (f + 1 < frames && !gpu.value()->render(positions[f + 1]).is_ok()) return 1;
      const SoftLights soft = soft_lights(downsample_cube(*cube, shrink));
      if (soft.lights.size() != 64) return 1;
      if (f + 1 < frames) cube = gpu.value()->read_back();
      if (!cube) return 1;
    }
    const double wall = ms_since(t0) / frames, cpu = (cpu_ms() - cpu0) / frames;
    std::printf("  pipelined total     %7.2f ms per frame (%.1f frames/s), process CPU time %.2f ms per frame\n", wall,
                1e3 / wall, cpu);
  }

  // For comparison: the same cube fused on the CPU (one thread), and soft lights on the full-size cube.
  const int cpu_frames = std::min(frames, 5);
  auto t0 = std::chrono::steady_clock::now();
  for (int f = 0; f < cpu_frames; ++f)
    if (!fuse_cube(probes, positions[f], testing::kSyntheticRoom, size)) return 1;
  std::printf("CPU fusion of the same cube (probe::fuse_cube, one thread): %.1f ms per frame\n",
              ms_since(t0) / cpu_frames);
  auto cube = gpu.value()->fuse(positions[0]);
  t0 = std::chrono::steady_clock::now();
  (void)soft_lights(*cube);
  std::printf("soft:64 lights on the full 6 x %d^2 cube: %.1f ms\n", size, ms_since(t0));
  return 0;
}

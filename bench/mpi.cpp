// Strong scaling of the MPI driver (cluster/, docs/scale.md) on this machine: a simulated session's observation-map
// build on 1 and 2 ranks, and a Phong-1 fit on 1 rank and on 1 and 2 worker ranks (rank 0 only hands tiles out
// when there are workers), each rank one thread; then the per-tile figures the cost model at scale is built from,
// measured in process: observation-tile read, fit compute, record write and sizes.
//   bench_mpi [--res N] [--obsmap-res N] [--scheme latlong:K]   (defaults 128, 512, latlong:6)
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "vdrig/cluster/tile_store.hpp"
#include "vdrig/fitting/tiled_fit.hpp"
#include "vdrig/test/build_paths.hpp"

namespace fs = std::filesystem;
using namespace vdrig;

namespace {

double now_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

/// Runs a shell command, output to `log`; returns its wall time (exits on failure).
double run(const std::string& cmd, const fs::path& log) {
  const double t0 = now_s();
  const int status = std::system((cmd + " >'" + log.string() + "' 2>&1").c_str());
  const double wall = now_s() - t0;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "failed (%d): %s\nsee %s\n", status, cmd.c_str(), log.c_str());
    std::exit(1);
  }
  return wall;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

int main(int argc, char** argv) {
  int res = 128, obsmap_res = 512;
  std::string scheme = "latlong:6";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::string(argv[i]) == "--res") res = std::atoi(argv[i + 1]);
    if (std::string(argv[i]) == "--obsmap-res") obsmap_res = std::atoi(argv[i + 1]);
    if (std::string(argv[i]) == "--scheme") scheme = argv[i + 1];
  }
  const std::string vdrig = VDRIG_CLI_PATH;
  std::string mpirun = std::string(VDRIG_MPIEXEC) + " " + VDRIG_MPIEXEC_FLAGS;
  if (::geteuid() == 0) mpirun += " --allow-run-as-root";
  const fs::path dir = fs::temp_directory_path() / ("vdrig_bench_mpi_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path log = dir / "log.txt", session = dir / "session";
  {
    std::ofstream rig(dir / "rig.json");
    rig << R"({"stage": {"backend": "sim"}, "camera": {"backend": "sim"}, "light": {"backend": "sim"},
               "sim": {"scene": "patchwork", "camera": {"width": 320, "height": 240, "fx": 400.0, "fy": 400.0}}})";
  }
  run(vdrig + " capture --rig " + (dir / "rig.json").string() + " --scheme " + scheme +
          " --bracket fixed:1,0.25 --out " + session.string(),
      log);
  run(vdrig + " hdr " + session.string(), log);
  const double launch = run(mpirun + " -n 2 true", log);
  std::printf("mpirun -n 2 start and end (no work): %.2f s\n", launch);
  // The build's sampling grows with the texels, its view reading does not: a larger map for the build.
  const std::string rb = std::to_string(obsmap_res) + "x" + std::to_string(obsmap_res);
  const fs::path big1 = dir / "big1.vdobs", big2 = dir / "big2.vdobs";
  const std::string big = " obsmap build " + session.string() + " --res " + rb + " --compression none --out ";
  const double b1 = run(vdrig + big + big1.string(), log);
  const double b2 = run(mpirun + " -n 2 " + vdrig + big + big2.string() + " --mpi", log);
  const bool same = slurp(big1) == slurp(big2);
  // The same with one OpenCV thread per process: each rank then uses one core, as a rank per core would.
  const std::string one_thread = "env OPENCV_FOR_THREADS_NUM=1 ";
  const double c1 = run(one_thread + vdrig + big + big1.string(), log);
  const double c2 =
      run(one_thread + mpirun + " -n 2 -x OPENCV_FOR_THREADS_NUM " + vdrig + big + big2.string() + " --mpi", log);
  const uintmax_t big_bytes = fs::file_size(big1);
  fs::remove(big2);
  std::printf("obsmap build %s (%.0f MB): 1 rank %.2f s, 2 ranks %.2f s (speedup %.2fx); files identical: %s\n",
              rb.c_str(), big_bytes / 1e6, b1, b2, b1 / b2, same ? "yes" : "NO");
  std::printf("obsmap build %s, 1 thread per process: 1 rank %.2f s, 2 ranks %.2f s (speedup %.2fx)\n", rb.c_str(), c1,
              c2, c1 / c2);

  const std::string r = std::to_string(res) + "x" + std::to_string(res);
  const fs::path obs1 = dir / "one.vdobs";
  run(vdrig + " obsmap build " + session.string() + " --res " + r + " --compression none --out " + obs1.string(), log);
  auto reader = fitting::ObsMapReader::open(obs1);
  if (!reader) return std::fprintf(stderr, "%s\n", reader.error().describe().c_str()), 1;
  const int views = reader->views(), tiles = reader->tiles_s() * reader->tiles_t();
  std::printf("session: %s, %d views; observation map %s x %d views, %d tiles of 32x32, %.1f MB\n", scheme.c_str(),
              views, r.c_str(), views, tiles, reader->header().file_bytes / 1e6);

  const std::string fit = " fit " + session.string() + " --obsmap " + obs1.string() + " --model phong:1 --threads 1";
  const double f0 = run(vdrig + fit + " --out " + (dir / "single.exr").string(), log);
  const double f1 = run(mpirun + " -n 1 " + vdrig + fit + " --out " + (dir / "n1.exr").string() + " --mpi", log);
  const double f2 = run(mpirun + " -n 2 " + vdrig + fit + " --out " + (dir / "n2.exr").string() + " --mpi", log);
  const double f3 = run(mpirun + " -n 3 " + vdrig + fit + " --out " + (dir / "n3.exr").string() + " --mpi", log);
  std::printf(
      "phong:1 fit, 1 thread per rank: single process %.2f s; mpirun -n 1 %.2f s; -n 2 (1 worker) %.2f s; "
      "-n 3 (2 workers) %.2f s: speedup 1 -> 2 workers %.2fx\n",
      f0, f1, f2, f3, f2 / f3);

  // Per tile, in process (1 thread): what a rank spends on one tile.
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("phong:1").value();
  options.threads = 1;
  auto tiled = fitting::TiledMapFit::create(reader.value(), options);
  auto store = cluster::TileStore::open(dir / "tiles", "bench", true);
  if (!tiled || !store) return 1;
  double read_s = 0, fit_s = 0, write_s = 0, record_bytes = 0;
  for (int k = 0; k < tiles; ++k) {
    const double t0 = now_s();
    auto tile = reader->read_tile(k % reader->tiles_s(), k / reader->tiles_s());
    const double t1 = now_s();
    auto record = tiled->fit_tile(0, k, nullptr);  // reads the tile again, then fits
    const double t2 = now_s();
    if (!tile || !record || !store->write(0, k, record.value())) return 1;
    const double t3 = now_s();
    read_s += t1 - t0;
    fit_s += (t2 - t1) - (t1 - t0);
    write_s += t3 - t2;
    record_bytes += static_cast<double>(record->size());
  }
  const double texels_per_tile = static_cast<double>(res) * res / tiles;
  std::printf(
      "per tile (%.0f texels x %d views, %.2f MB of observations): read %.1f ms, fit %.0f ms (%.3f ms/texel), "
      "record %.1f kB written in %.1f ms (fsync'd)\n",
      texels_per_tile, views, texels_per_tile * views * 25 / 1e6, 1e3 * read_s / tiles, 1e3 * fit_s / tiles,
      1e3 * fit_s / tiles / texels_per_tile, record_bytes / tiles / 1e3, 1e3 * write_s / tiles);
  fs::remove(big1);
  fs::remove(big2);
  // Phong-K: phong:auto (up to 4 lobes, chosen by BIC) on the first 4 tiles.
  options.model = fitting::parse_model("phong:auto").value();
  auto tiled_auto = fitting::TiledMapFit::create(reader.value(), options);
  if (!tiled_auto) return 1;
  const double a0 = now_s();
  for (int k = 0; k < 4; ++k)
    if (!tiled_auto->fit_tile(0, k, nullptr)) return 1;
  const double auto_s = (now_s() - a0) / 4;
  std::printf("per tile, phong:auto: fit %.0f ms (%.3f ms/texel)\n", 1e3 * auto_s, 1e3 * auto_s / texels_per_tile);
  std::printf("obsmap build %s per view: 1 rank %.1f ms, 2 ranks %.1f ms\n", rb.c_str(), 1e3 * b1 / views,
              1e3 * b2 / views);
  fs::remove_all(dir);
  return 0;
}

#include "vdrig/cluster/distributed_obsmap.hpp"

#include <fmt/format.h>

#include <chrono>

#include "vdrig/core/log.hpp"

namespace vdrig::cluster {
namespace fs = std::filesystem;

Status build_obsmap_distributed(Comm& comm, int T, const fitting::ObsFileOptions& file, const fs::path& path,
                                const ObsMapPartBuilder& build_part) {
  const int rank = comm.rank(), ranks = comm.size();
  auto part_path = [&](int r) { return fs::path(path.string() + fmt::format(".part-{}-of-{}", r, ranks)); };
  fitting::ObsFileOptions mine = file;
  const int tile = std::max(1, file.tile_size);
  const int rows = (T + tile - 1) / tile;
  mine.first_tile_row = static_cast<int>(static_cast<long long>(rows) * rank / ranks);
  mine.end_tile_row = static_cast<int>(static_cast<long long>(rows) * (rank + 1) / ranks);
  auto logger = log::get("cluster");
  const auto start = std::chrono::steady_clock::now();
  VDRIG_TRY(build_part(mine, part_path(rank)));
  logger->info("rank {}: tile rows [{}, {}) of {} written to {} in {:.2f} s", rank, mine.first_tile_row,
               mine.end_tile_row, rows, part_path(rank).string(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  VDRIG_TRY(comm.barrier());
  Status assembled = Status::ok();
  if (rank == 0) {
    std::vector<fs::path> parts;
    for (int r = 0; r < ranks; ++r) parts.push_back(part_path(r));
    assembled = fitting::assemble_obsmap_parts(parts, path);
    if (assembled)
      for (const fs::path& p : parts) fs::remove(p);
  }
  // Everyone returns once the file is there (or rank 0's error ends the job).
  VDRIG_TRY(assembled);
  return comm.barrier();
}

}  // namespace vdrig::cluster

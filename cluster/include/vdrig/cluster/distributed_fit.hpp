// A parameter-map fit over the ranks of a Comm (MPI), restartable tile by tile (docs/scale.md).
//
// Every rank opens the same observation-map file (a shared filesystem) and builds the same fitting::TiledMapFit.
// Rank 0 hands the tiles out one at a time (a master/worker loop: a worker's "done" message asks for the next tile);
// with more than one rank, rank 0 only hands out, logs and assembles, and fits nothing. Each finished tile is
// recorded in the TileStore before it is reported, so a job that dies resumes with the tiles not recorded. With
// shared lights, each worker's "done" message of the first pass carries the tile's lobe rays (the gather), rank 0
// estimates the lights from all of them in texel order and broadcasts them, then the refit pass runs.
// The map equals fitting::fit_parameter_map's bit for bit (tests/cluster).
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "vdrig/cluster/comm.hpp"
#include "vdrig/cluster/tile_store.hpp"
#include "vdrig/fitting/tiled_fit.hpp"

namespace vdrig::cluster {

struct DistributedFitOptions {
  /// Where the tile records go (TileStore root), e.g. `maps/<model>.exr.tiles`.
  std::filesystem::path tiles_root;
  /// Called on rank 0 after each recorded tile (pass, tiles done in the pass, tiles in the pass).
  std::function<void(int pass, int done, int total)> on_tile;
  /// TEST HOOK (tests/cluster/test_mpi_fit.cpp): when > 0, a worker rank exits at once with status 42, without
  /// MPI_Finalize, right after recording this many tiles: a rank lost mid-fit. 0 in normal use.
  int test_exit_after_tiles = 0;
};

/// The fingerprint of a fit of `obs` with `options`: fitting::fit_options_fingerprint plus the file's identity
/// (size, tiling, compression and index checksum).
std::string fit_fingerprint(const fitting::ObsMapReader& obs, const fitting::MapFitOptions& options);

/// Runs the fit on every rank of `comm` (each calls it). Returns the map on rank 0, std::nullopt on the others. A
/// tile that fails on a worker is reported to rank 0, whose error names the rank, the pass and the tile; the caller
/// ends the job on any error (Comm::abort) so that no rank waits forever.
Result<std::optional<fitting::ParameterMap>> fit_distributed(Comm& comm, const fitting::ObsMapReader& obs,
                                                             const fitting::MapFitOptions& options,
                                                             const DistributedFitOptions& distributed);

}  // namespace vdrig::cluster

// An observation-map file built by the ranks of a Comm (MPI), split by tile rows (docs/scale.md).
//
// What a rank samples into its rows is the caller's ObsMapPartBuilder (for a session, `vdrig obsmap build --mpi`
// passes pipeline::build_session_obsmap_file): cluster only splits, waits and assembles, so MPI ranks link neither
// the pipeline nor, through it, OpenGL and the simulator.
//
// Rank r of N samples tile rows [r * R / N, (r + 1) * R / N) of the R rows: it reads every HDR view (the cost that
// does not shrink with N) and writes only its rows, to its own part file beside the result
// (`<path>.part-<r>-of-<N>`, written, fsynced and renamed by that rank alone). After a barrier rank 0 joins the
// parts (fitting::assemble_obsmap_parts) into `path`, byte for byte the file a single process writes, and removes
// them. Why parts rather than every rank writing into one shared file: a part has one writer, so nothing depends
// on how a shared filesystem orders or caches concurrent writes to one file (NFS's close-to-open consistency is
// all it needs: rank 0 opens each part after its writer closed it), and the tile offsets, which depend on every
// compressed tile before them, are only known once every part is done. The cost is one more sequential copy of the
// file by rank 0.
#pragma once

#include <filesystem>
#include <functional>

#include "vdrig/cluster/comm.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::cluster {

/// Writes one rank's part: the observation map's tile rows [rows.first_tile_row, rows.end_tile_row) to `part`
/// (an ObsMapWriter created with `rows` as its ObsFileOptions).
using ObsMapPartBuilder = std::function<Status(const fitting::ObsFileOptions& rows, const std::filesystem::path& part)>;

/// Every rank calls it with the same arguments (`texels_t` the map's height in texels, `file` its options);
/// `build_part` is called once on each rank with `file` narrowed to that rank's tile rows. Returns once `path` is
/// complete (on every rank). The caller ends the job on an error (Comm::abort): a rank that failed never reaches
/// the barrier the others wait at.
Status build_obsmap_distributed(Comm& comm, int texels_t, const fitting::ObsFileOptions& file,
                                const std::filesystem::path& path, const ObsMapPartBuilder& build_part);

}  // namespace vdrig::cluster

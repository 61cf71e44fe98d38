// A session's observation-map file built by the ranks of a Comm (MPI), split by tile rows (docs/scale.md).
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

#include "vdrig/capture/session.hpp"
#include "vdrig/cluster/comm.hpp"
#include "vdrig/pipeline/obsmap_stage.hpp"

namespace vdrig::cluster {

/// Every rank calls it with the same arguments; returns once `path` is complete (on every rank). options.file's
/// tile rows are set here. The caller ends the job on an error (Comm::abort): a rank that failed never reaches the
/// barrier the others wait at.
Status build_session_obsmap_distributed(Comm& comm, const capture::Session& session, int texels_s, int texels_t,
                                        const std::filesystem::path& path,
                                        const pipeline::ObsMapBuildOptions& options = {});

}  // namespace vdrig::cluster

// `--mpi` of vdrig fit and vdrig obsmap build: the MPI world (cluster/comm.hpp) and how a command ends in a job.
#pragma once

#include "commands.hpp"
#include "vdrig/cluster/comm.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::app {

/// In an MPI job an error must end every rank (MPI_Abort), or the others would wait for this one forever; the
/// error is logged first, naming the rank. Outside a job: finish(status).
inline void finish_job(const Status& status) {
  if (!status && cluster::world_started()) {
    auto comm = cluster::world();
    log::get("app")->error("rank {} of {}: {}", comm.value()->rank(), comm.value()->size(), status.describe());
    comm.value()->abort(status.error().code == ErrorCode::kInvalidArgument ? kExitUsage : kExitFailure);
  }
  finish(status);
}

}  // namespace vdrig::app

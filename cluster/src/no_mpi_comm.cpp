// A build without MPI (VDRIG_WITH_MPI off or MPI not found): --mpi is refused with the reason.
#include "vdrig/cluster/comm.hpp"

namespace vdrig::cluster {

bool built_with_mpi() { return false; }

bool world_started() { return false; }

Result<Comm*> world() {
  return make_error(ErrorCode::kUnsupported,
                    "this vdrig was built without MPI (install libopenmpi-dev, configure with -DVDRIG_WITH_MPI=ON)");
}

}  // namespace vdrig::cluster

// The message passing the distributed fit and observation-map build need, behind a small interface so that MPI's
// headers stay private to this module (src/mpi_comm.cpp is the only file that includes mpi.h; it is compiled only
// when vdrig is built with MPI, VDRIG_WITH_MPI). docs/scale.md describes the protocol built on it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::cluster {

using Bytes = std::vector<uint8_t>;

struct Message {
  int from = -1;
  int tag = 0;
  Bytes bytes;
};

/// A group of processes (ranks 0 .. size - 1), each running the same command. Called from one thread only.
class Comm {
 public:
  virtual ~Comm() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Sends `bytes` to rank `to` with `tag` (>= 0).
  virtual Status send(int to, int tag, const Bytes& bytes) = 0;
  /// The next message from rank `from` (-1: any rank). Waits by polling with short sleeps, so a rank waiting for
  /// work does not spin a core the fit's threads need.
  virtual Result<Message> receive(int from = -1) = 0;
  /// Rank `root`'s bytes on every rank (`bytes` is ignored elsewhere).
  virtual Result<Bytes> broadcast(const Bytes& bytes, int root = 0) = 0;
  /// Waits (polling, as receive) until every rank has called it.
  virtual Status barrier() = 0;
  /// Ends every rank of the job with `code` (MPI_Abort): the way out of an error that other ranks would otherwise
  /// wait on forever.
  [[noreturn]] virtual void abort(int code) = 0;
};

/// True when this build has MPI (VDRIG_WITH_MPI and the library was found).
bool built_with_mpi();

/// The world communicator of a process started by mpirun (MPI_Init_thread, funneled: only the calling thread
/// talks MPI; MPI_Finalize runs at exit). Created once per process; later calls return the same one.
/// kUnsupported when vdrig was built without MPI.
Result<Comm*> world();

/// True when world() has been created in this process (so errors must end the whole job: Comm::abort).
bool world_started();

}  // namespace vdrig::cluster

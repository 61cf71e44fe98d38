// Comm over MPI: the one file of vdrig that includes mpi.h.
#include <mpi.h>

#include <chrono>
#include <cstdlib>
#include <thread>

#include "vdrig/cluster/comm.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::cluster {
namespace {

bool g_started = false;

std::string mpi_error(int code) {
  char text[MPI_MAX_ERROR_STRING];
  int n = 0;
  MPI_Error_string(code, text, &n);
  return std::string(text, static_cast<size_t>(n));
}

Error failed(const std::string& what, int code) { return make_error(ErrorCode::kIo, what + ": " + mpi_error(code)); }

/// Sleep between polls: short against a tile's fit (seconds), long enough not to load a core.
void pause() { std::this_thread::sleep_for(std::chrono::microseconds(200)); }

class MpiComm final : public Comm {
 public:
  MpiComm() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }

  Status send(int to, int tag, const Bytes& bytes) override {
    const int rc = MPI_Send(bytes.data(), static_cast<int>(bytes.size()), MPI_BYTE, to, tag, MPI_COMM_WORLD);
    if (rc != MPI_SUCCESS) return failed("MPI_Send to rank " + std::to_string(to), rc);
    return Status::ok();
  }

  Result<Message> receive(int from) override {
    const int source = from < 0 ? MPI_ANY_SOURCE : from;
    MPI_Status status;
    for (int flag = 0;;) {
      const int rc = MPI_Iprobe(source, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (rc != MPI_SUCCESS) return failed("MPI_Iprobe", rc);
      if (flag) break;
      pause();
    }
    int count = 0;
    MPI_Get_count(&status, MPI_BYTE, &count);
    Message m;
    m.from = status.MPI_SOURCE;
    m.tag = status.MPI_TAG;
    m.bytes.resize(static_cast<size_t>(count));
    const int rc = MPI_Recv(m.bytes.data(), count, MPI_BYTE, m.from, m.tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    if (rc != MPI_SUCCESS) return failed("MPI_Recv from rank " + std::to_string(m.from), rc);
    return m;
  }

  Result<Bytes> broadcast(const Bytes& bytes, int root) override {
    uint64_t n = rank_ == root ? bytes.size() : 0;
    VDRIG_TRY(wait_for(MPI_Ibcast(&n, 1, MPI_UINT64_T, root, MPI_COMM_WORLD, &request_), "MPI_Ibcast"));
    Bytes out = rank_ == root ? bytes : Bytes(n);
    // Counts are ints in MPI: larger states go in pieces.
    constexpr uint64_t kPiece = uint64_t{1} << 30;
    for (uint64_t at = 0; at < n; at += kPiece) {
      const int piece = static_cast<int>(std::min(kPiece, n - at));
      VDRIG_TRY(wait_for(MPI_Ibcast(out.data() + at, piece, MPI_BYTE, root, MPI_COMM_WORLD, &request_), "MPI_Ibcast"));
    }
    return out;
  }

  Status barrier() override { return wait_for(MPI_Ibarrier(MPI_COMM_WORLD, &request_), "MPI_Ibarrier"); }

  [[noreturn]] void abort(int code) override {
    log::get("cluster")->flush();
    MPI_Abort(MPI_COMM_WORLD, code);
    std::_Exit(code);  // MPI_Abort does not return; if it did, the job must still end
  }

 private:
  /// Completes the nonblocking operation just started (rc its start's return code), polling.
  Status wait_for(int rc, const char* what) {
    if (rc != MPI_SUCCESS) return failed(what, rc);
    for (int done = 0;;) {
      rc = MPI_Test(&request_, &done, MPI_STATUS_IGNORE);
      if (rc != MPI_SUCCESS) return failed(what, rc);
      if (done) return Status::ok();
      pause();
    }
  }

  int rank_ = 0, size_ = 1;
  MPI_Request request_ = MPI_REQUEST_NULL;
};

void finalize_at_exit() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

}  // namespace

bool built_with_mpi() { return true; }

bool world_started() { return g_started; }

Result<Comm*> world() {
  static MpiComm* comm = [] {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) {
      int provided = 0;
      MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
      std::atexit(finalize_at_exit);
    }
    // Errors come back as codes (and so as Status values) rather than aborting inside MPI.
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    g_started = true;
    return new MpiComm();  // lives until exit: MPI is finalised at exit
  }();
  return static_cast<Comm*>(comm);
}

}  // namespace vdrig::cluster

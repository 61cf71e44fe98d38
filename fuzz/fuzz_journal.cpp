// Session::open replaying a journal: the input is journal.jsonl of a session whose manifest is valid (two views).
// Whatever the lines hold, open() returns a session or an error; a session's frames and views are then queried as
// the stages do.
#include "fuzz_support.hpp"
#include "vdrig/capture/session.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = fuzz::scratch_dir() / "session";
    capture::Manifest manifest;
    manifest.scheme = "fuzz";
    manifest.bracket = "fixed:0.01";
    manifest.exposures_s = {0.01};
    manifest.views = {capture::PlannedView{0, Vec3d::UnitZ(), {}}, capture::PlannedView{1, Vec3d::UnitX(), {}}};
    if (!capture::Session::create(d, manifest)) std::abort();
    return d;
  }();
  fuzz::write_bytes(dir / "journal.jsonl", data, size);
  auto session = capture::Session::open(dir);
  if (session) {
    for (int v = -1; v <= 2; ++v) {
      (void)session->frames_of_view(v);
      (void)session->view_complete(v);
      (void)session->view_frame_count(v);
    }
    (void)session->completed_view_count();
  }
  return 0;
}

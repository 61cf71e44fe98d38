// Session::open reading manifest.json (then Manifest::from_json), with an empty journal; a manifest it accepts must
// write back (to_json) and read again to an equal view list.
#include "fuzz_support.hpp"
#include "vdrig/capture/session.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = fuzz::scratch_dir() / "session";
    std::filesystem::create_directories(d);
    std::ofstream(d / "journal.jsonl").flush();
    return d;
  }();
  fuzz::write_bytes(dir / "manifest.json", data, size);
  auto session = capture::Session::open(dir);
  if (!session) return 0;
  const capture::Manifest& m = session->manifest();
  auto again = capture::Manifest::from_json(m.to_json());
  if (!again || again->views.size() != m.views.size()) std::abort();
  return 0;
}

// load_probe on an OpenEXR light probe (panorama layout, and resampled to a small width as `probe fuse` may ask).
#include "fuzz_exr.hpp"
#include "vdrig/probe/probe.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path path = fuzz::exr_scratch_file("probe.exr");
  fuzz::write_bytes(path, data, size);
  (void)probe::load_probe(path);
  probe::LoadOptions small;
  small.width = 8;
  (void)probe::load_probe(path, small);
  return 0;
}

// ObsMapReader on a .vdobs file: open() (header, index), then tiles as fit reads them, and the whole map when it is
// small. Checksums are not checked in the fuzzing build (FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION), so mutated
// headers and tiles reach the size checks and the decompressor.
#include "fuzz_support.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path path = fuzz::scratch_dir() / "map.vdobs";
  fuzz::write_bytes(path, data, size);
  auto reader = fitting::ObsMapReader::open(path);
  if (!reader) return 0;
  int read = 0;
  for (int tt = 0; tt < reader->tiles_t() && read < 16; ++tt)
    for (int ts = 0; ts < reader->tiles_s() && read < 16; ++ts, ++read) {
      auto tile = reader->read_tile(ts, tt);
      if (!tile) continue;
      for (int v = 0; v < tile->views(); ++v) (void)tile->flag(tile->s0(), tile->t0(), v);
      (void)tile->texel(tile->s0() + tile->width() - 1, tile->t0() + tile->height() - 1, {0});
    }
  const fitting::ObservationMapSpec& spec = reader->spec();
  if (static_cast<int64_t>(spec.texels_s) * spec.texels_t * reader->views() <= 4096) (void)reader->read_all();
  return 0;
}

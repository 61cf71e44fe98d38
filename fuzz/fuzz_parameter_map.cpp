// ParameterMap::read on an OpenEXR file (fitted maps: header attributes name the model, channels hold it); a map it
// accepts is evaluated at a few texels as the viewer and renderer do.
#include "fuzz_exr.hpp"
#include "vdrig/fitting/parameter_map.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path path = fuzz::exr_scratch_file("map.exr");
  fuzz::write_bytes(path, data, size);
  auto map = fitting::ParameterMap::read(path);
  if (!map) return 0;
  const int s_max = map->texels_s() - 1, t_max = map->texels_t() - 1;
  if (s_max < 0 || t_max < 0) return 0;
  for (const auto& [s, t] : {std::pair{0, 0}, std::pair{s_max, t_max}, std::pair{s_max / 2, t_max / 2}})
    (void)map->evaluate(s, t, Vec3d(0.3, 0.2, 0.9).normalized());
  return 0;
}

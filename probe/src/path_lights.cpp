#include "vdrig/probe/path_lights.hpp"

#include <cstdio>
#include <string>

#include "vdrig/core/file_write.hpp"
#include "vdrig/probe/probe_json.hpp"

namespace vdrig::probe {
namespace fs = std::filesystem;

Status write_path_lights(const std::vector<Probe>& probes, const ProxyBox& room, const std::vector<Vec3d>& positions_mm,
                         const IrradianceMethodSpec& method, const FusionOptions& fusion, const fs::path& out_dir) {
  if (method.method == IrradianceMethod::kExact)
    return make_error(ErrorCode::kInvalidArgument, "the exact method has no lights to write");
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + out_dir.string() + ": " + ec.message());
  for (size_t f = 0; f < positions_mm.size(); ++f) {
    auto fused = fuse(probes, positions_mm[f], room, fusion);
    if (!fused) return fused.error();
    const IrradianceModel m = IrradianceModel::build(*fused, method);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04zu", f);
    const std::string base = (out_dir / name).string();
    const std::string source = "fused at frame " + std::to_string(f);
    VDRIG_TRY(write_file_atomic(base + ".lights.json", lights_to_json({source, m.lights()})));
    if (m.sh9()) VDRIG_TRY(write_file_atomic(base + ".sh9.json", sh9_to_json({source, *m.sh9()})));
  }
  return Status::ok();
}

}  // namespace vdrig::probe

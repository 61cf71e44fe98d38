#include "vdrig/probe/room_probes.hpp"

#include <string>
#include <utility>

namespace vdrig::probe {
namespace fs = std::filesystem;

Result<std::vector<Probe>> load_room_probes(const fs::path& room_file, const RoomDocument& room,
                                            const LoadOptions& options) {
  const fs::path base = room_file.parent_path();
  std::vector<Probe> probes;
  for (size_t k = 0; k < room.probes.size(); ++k) {
    const RoomProbe& rp = room.probes[k];
    const fs::path file = fs::path(rp.file).is_absolute() ? fs::path(rp.file) : base / rp.file;
    auto p = load_probe(file, options);
    if (!p)
      return make_error(p.error().code, room_file.string() + ": probe " + std::to_string(k) + ": " + p.error().message);
    if (rp.has_position) p->position_mm = rp.position_mm;
    probes.push_back(std::move(p.value()));
  }
  return probes;
}

}  // namespace vdrig::probe

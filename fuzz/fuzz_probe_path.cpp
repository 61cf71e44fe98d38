// A "vdrig.probe.path" file (`vdrig probe path|animate --path PATH.json`) as the app reads it: path_from_json, then
// validate_path against a fixed room with a sphere's margin, then sample_path over a few frames. Checks what the
// app relies on: an accepted path round-trips through path_to_json, and a validated path's samples are finite and
// stay inside the room (it is convex and every key is inside), including the first and last keys exactly.
#include <nlohmann/json.hpp>

#include "fuzz_support.hpp"
#include "vdrig/probe/object_path.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = ((void)fuzz::scratch_dir(), true);  // quiet logs
  (void)quiet;
  static const probe::ProxyBox kRoom{Vec3d(-2000, -1500, 0), Vec3d(2000, 1500, 2600)};
  constexpr double kMarginMm = 100;
  const std::string text = fuzz::as_string(data, size);
  auto path = probe::path_from_json(text);
  if (!path) return 0;
  const auto doc = nlohmann::json::parse(text, nullptr, false);
  VDRIG_CHECK(doc.is_object() && doc.at("version") == nlohmann::json(1),
              "path_from_json accepted a version other than 1");
  auto back = probe::path_from_json(probe::path_to_json(*path));
  VDRIG_CHECK(back.is_ok() && back->keys.size() == path->keys.size(), "path_to_json wrote a path it cannot read");
  for (size_t k = 0; k < path->keys.size(); ++k) {
    const probe::PathKey& a = path->keys[k];
    const probe::PathKey& b = back->keys[k];
    // Non-finite values cannot be in JSON text, so a parsed path has none to compare.
    VDRIG_CHECK(a.time_s == b.time_s && a.position_mm == b.position_mm, "path key does not round-trip");
  }
  if (!probe::validate_path(*path, kRoom, kMarginMm)) return 0;
  for (const int frames : {1, 2, 7}) {
    const std::vector<Vec3d> positions = probe::sample_path(*path, frames);
    VDRIG_CHECK(positions.size() == static_cast<size_t>(frames), "sample_path returned the wrong frame count");
    VDRIG_CHECK(positions.front() == path->keys.front().position_mm, "the first frame is not the first key");
    if (frames > 1)
      VDRIG_CHECK(positions.back() == path->keys.back().position_mm, "the last frame is not the last key");
    for (const Vec3d& p : positions)
      VDRIG_CHECK(p.allFinite() && kRoom.contains(p), "a sampled position leaves the room (or is not finite)");
  }
  return 0;
}

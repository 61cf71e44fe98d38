// A "vdrig.probe.room" file (`vdrig probe animate ROOM.json`) through room_from_json, the JSON-level parse and
// validation. The probe files it names are not loaded: loading is the caller's (load_room_probes in the app), and a
// fuzzer that followed the names could read any file on the machine; the EXR reader has its own target
// (fuzz_probe_exr). An accepted room must be what the format allows and must round-trip through room_to_json.
#include <nlohmann/json.hpp>

#include "fuzz_support.hpp"
#include "vdrig/probe/probe_json.hpp"

using namespace vdrig;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = ((void)fuzz::scratch_dir(), true);  // quiet logs
  (void)quiet;
  const std::string text = fuzz::as_string(data, size);
  auto room = probe::room_from_json(text);
  if (!room) return 0;
  // What was accepted, checked against the text itself: version exactly 1 (not a number that casts to 1).
  const auto doc = nlohmann::json::parse(text, nullptr, false);
  VDRIG_CHECK(doc.is_object() && doc.at("version") == nlohmann::json(probe::kRoomFormatVersion),
              "room_from_json accepted a version other than 1");
  VDRIG_CHECK(room->room.is_valid() && !room->probes.empty(), "room_from_json accepted an invalid room");
  for (const auto& p : room->probes)
    VDRIG_CHECK(!p.file.empty() && p.position_mm.allFinite(), "room_from_json accepted a bad probe");
  auto back = probe::room_from_json(probe::room_to_json(*room));
  VDRIG_CHECK(back.is_ok(), "room_to_json wrote a room room_from_json rejects");
  VDRIG_CHECK(back->room.min_mm == room->room.min_mm && back->room.max_mm == room->room.max_mm &&
                  back->probes.size() == room->probes.size(),
              "room does not round-trip");
  for (size_t k = 0; k < room->probes.size(); ++k) {
    const auto& a = room->probes[k];
    const auto& b = back->probes[k];
    VDRIG_CHECK(a.file == b.file && a.has_position == b.has_position && a.position_mm == b.position_mm,
                "room probe does not round-trip");
  }
  return 0;
}

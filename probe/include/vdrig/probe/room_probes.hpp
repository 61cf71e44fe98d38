// The probes a room file names (probe_json.hpp's RoomDocument), loaded and placed: what `vdrig probe animate` fuses.
#pragma once

#include <filesystem>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/probe_json.hpp"

namespace vdrig::probe {

/// Every probe of `room` loaded with `options` (relative file names resolved against room_file's folder), its
/// position set to the room's where the room gives one (else the position stored in the file). Errors: load_probe's,
/// prefixed with "<room_file>: probe <k>: ".
Result<std::vector<Probe>> load_room_probes(const std::filesystem::path& room_file, const RoomDocument& room,
                                            const LoadOptions& options = {});

}  // namespace vdrig::probe

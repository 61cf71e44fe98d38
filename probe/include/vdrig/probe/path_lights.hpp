// Lights for an object moving along a path (`vdrig probe path`, docs/probe.md): the probes fused at each frame's
// position on the box proxy, turned into lights by an irradiance method, one JSON file per frame.
#pragma once

#include <filesystem>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/irradiance_map.hpp"
#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

/// For each position k, the probes fused there (fuse) and made into `method`'s lights, written to
/// out_dir/frame_KKKK.lights.json (lights_to_json), and out_dir/frame_KKKK.sh9.json (sh9_to_json) for methods with an
/// SH-9 part. out_dir is created when missing. Errors: kInvalidArgument for the exact method (it has no lights) and
/// what fuse() rejects; kIo/kNoSpace when writing.
Status write_path_lights(const std::vector<Probe>& probes, const ProxyBox& room, const std::vector<Vec3d>& positions_mm,
                         const IrradianceMethodSpec& method, const FusionOptions& fusion,
                         const std::filesystem::path& out_dir);

}  // namespace vdrig::probe

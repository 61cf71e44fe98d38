// A virtual object's path through the proxy room (fusion.hpp): positions over time, for lighting the object frame
// by frame with the probe fused at its position (docs/probe.md, "The moving object").
#pragma once

#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/fusion.hpp"

namespace vdrig::probe {

/// One key of a path: where the object's centre is (world mm) at time_s.
struct PathKey {
  double time_s = 0;
  Vec3d position_mm = Vec3d::Zero();
};

/// `ObjectPath`: keys with strictly increasing times; the position between keys is linear in time, constant
/// before the first and after the last.
struct ObjectPath {
  std::vector<PathKey> keys;

  double duration_s() const { return keys.empty() ? 0 : keys.back().time_s - keys.front().time_s; }
};

/// Rejects, with the reason (kInvalidArgument): an empty path, a non-finite time or position, times not strictly
/// increasing, a duration (last time - first) that is not finite as a double (times near +-1e308), and a key outside
/// the room or nearer than margin_mm to a wall (naming the key, its position and the wall). The room is convex, so a
/// path whose keys are inside stays inside between them.
Status validate_path(const ObjectPath& path, const ProxyBox& room, double margin_mm = 0);

/// Position at time_s (linear between keys, clamped at the ends). VDRIG_CHECKs a non-empty path; the path is one
/// validate_path accepts (for another, positions may be NaN).
Vec3d position_at(const ObjectPath& path, double time_s);

/// `frame_count` positions at equal time steps from the first key to the last (both included; one frame: the first
/// key, exactly). VDRIG_CHECKs a non-empty path and frame_count >= 1; the path is one validate_path accepts.
std::vector<Vec3d> sample_path(const ObjectPath& path, int frame_count);

/// Reads {"format": "vdrig.probe.path", "version": 1, "keys": [{"time_s": t, "position_mm": [x, y, z]}, ...]}.
/// kCorrupt naming the field for malformed JSON (also a "format" or "version" of the wrong type); the keys are not
/// validated against a room (validate_path). Never throws.
Result<ObjectPath> path_from_json(const std::string& text);
std::string path_to_json(const ObjectPath& path);

}  // namespace vdrig::probe

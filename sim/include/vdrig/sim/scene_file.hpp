// Scene files: the JSON form of a Scene (docs/sim.md has the format and a complete example). The keys are the
// names of Scene's fields; "format": "vdrig-scene" and "version": 1 identify the file. Every problem of a file is
// reported at once, each naming its JSON path and the rule ("materials[2].shininess: must be >= 1, got 0"), as one
// kInvalidArgument; a file that cannot be read is kIo. Saving then loading gives an equal scene (numbers are
// written with round-trip precision), so renders of the loaded scene are bit-identical.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/core/result.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::sim {

inline constexpr int kSceneFormatVersion = 1;

/// The scene described by `j`; `source` names it in error messages (a file name, "built-in scene bands"). Relative
/// "kd_image" paths are relative to `base_dir` (load_scene_file: the file's folder).
Result<Scene> parse_scene(const nlohmann::json& j, const std::string& source,
                          const std::filesystem::path& base_dir = {});
/// Reads and parses a scene file (kIo when unreadable, kInvalidArgument for bad JSON or a bad scene).
Result<Scene> load_scene_file(const std::string& path);
/// The JSON form of a valid scene (fields at their default value are left out where the format has a default).
nlohmann::ordered_json scene_to_json(const Scene& scene);
/// Writes scene_to_json(scene) to `path` (kIo on failure).
Status save_scene_file(const Scene& scene, const std::string& path);

}  // namespace vdrig::sim

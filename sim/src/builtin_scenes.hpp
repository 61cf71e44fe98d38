// The built-in scenes' files (sim/scenes/*.json), embedded at build time (builtin_scenes.cpp is generated).
#pragma once

#include <vector>

namespace vdrig::sim {

struct BuiltinSceneFile {
  const char* name;  // "patchwork"
  const char* json;  // the file's content
};

/// In the order of sim/CMakeLists.txt's sim_builtin_scenes (the order scene_names() lists them).
const std::vector<BuiltinSceneFile>& builtin_scene_files();

}  // namespace vdrig::sim

// Every ```json block of docs/*.md and README.md parses, and every rig config among them (an object with a "stage",
// "camera" or "light" section, or such a section alone) passes `vdrig rig check`'s validation: the examples users
// copy cannot drift from what the code accepts. Annotated schemas with comments or ellipses are fenced as jsonc.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

struct Block {
  std::string file;
  int line = 0;
  std::string text;
};

std::vector<Block> json_blocks(const fs::path& file) {
  std::ifstream in(file);
  std::vector<Block> blocks;
  std::string line;
  int number = 0;
  Block* open = nullptr;
  while (std::getline(in, line)) {
    ++number;
    const auto first = line.find_first_not_of(' ');
    const std::string trimmed = first == std::string::npos ? "" : line.substr(first);
    if (!open && trimmed == "```json") {
      blocks.push_back({file.filename().string(), number, ""});
      open = &blocks.back();
    } else if (open && trimmed.rfind("```", 0) == 0) {
      open = nullptr;
    } else if (open) {
      open->text += line + "\n";
    }
  }
  return blocks;
}

TEST(DocConfigs, EveryJsonBlockParsesAndEveryRigConfigIsValid) {
  rig::BackendRegistry registry;
  rig::register_hardware_backends(registry);
  sim::register_backends(registry);
  std::vector<fs::path> files = {fs::path(VDRIG_SOURCE_DIR) / "README.md"};
  for (const auto& e : fs::directory_iterator(fs::path(VDRIG_SOURCE_DIR) / "docs"))
    if (e.path().extension() == ".md") files.push_back(e.path());
  int rig_configs = 0, hardware_md_configs = 0;
  for (const auto& file : files) {
    for (const Block& b : json_blocks(file)) {
      SCOPED_TRACE(b.file + ":" + std::to_string(b.line));
      json parsed = json::parse(b.text, nullptr, false);
      // A section shown on its own ("camera": { ... }) is a member of the config object.
      if (parsed.is_discarded()) parsed = json::parse("{" + b.text + "}", nullptr, false);
      ASSERT_FALSE(parsed.is_discarded()) << "not JSON:\n" << b.text;
      if (!parsed.is_object() || !(parsed.contains("stage") || parsed.contains("camera") || parsed.contains("light")))
        continue;
      ++rig_configs;
      const bool complete = b.file == "hardware.md";
      hardware_md_configs += complete;
      const auto check = rig::check_rig_config(parsed, registry);
      for (const auto& problem : check.problems) {
        if (problem.find("in this build") != std::string::npos) continue;  // a backend this machine did not build
        if (!complete && problem.rfind("no \"", 0) == 0) continue;         // a fragment showing one section
        ADD_FAILURE() << problem;
      }
      if (parsed.contains("sim")) {
        auto sim = sim::SimConfig::from_json(parsed["sim"]);
        EXPECT_TRUE(sim) << sim.error().describe();
      }
    }
  }
  EXPECT_GE(hardware_md_configs, 7) << "docs/hardware.md has one example per hardware backend";
  EXPECT_GE(rig_configs, 9);
}

}  // namespace
}  // namespace vdrig

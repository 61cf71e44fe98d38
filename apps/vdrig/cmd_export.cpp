// `vdrig export MAP --format gltf|glb --out DIR`: a fitted BRDF map as a glTF 2.0 material on a quad of the sample's
// size (pipeline/gltf_export.hpp); view-only models are refused with the reason.
#include <cstdio>
#include <string>

#include "commands.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/gltf_export.hpp"

namespace vdrig::app {
namespace {

struct ExportArgs {
  std::string map, format = "gltf", out, name = "material";
};

Status run_export(const ExportArgs& a) {
  auto map = fitting::ParameterMap::read(a.map);
  if (!map) return map.error();
  auto written = pipeline::export_gltf(
      *map, a.out, a.name,
      a.format == "glb" ? pipeline::GltfContainer::kBinary : pipeline::GltfContainer::kSeparateFiles);
  if (!written) return written.error();
  if (written->clipped_texels > 0)
    log::get("app")->warn(
        "{} texels have an albedo above 1 (clamped in the base colour): is the light's intensity right?",
        written->clipped_texels);
  std::printf("wrote %s (%s, %dx%d texels, %.3f x %.3f m%s)\n", written->gltf.c_str(), map->model().name().c_str(),
              map->texels_s(), map->texels_t(), map->width_mm() / 1000.0, map->height_mm() / 1000.0,
              written->specular_extension ? ", KHR_materials_specular for F0" : "");
  return Status::ok();
}

const CommandRegistrar kExport([](CLI::App& root) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = root.add_subcommand("export", "Export a fitted BRDF map (ggx) as a glTF 2.0 material with PNG textures");
  cmd->add_option("map", args->map,
                  "parameter map (EXR, vdrig fit --model ggx:iso, ggx:iso+n, ggx:aniso or ggx:aniso+n)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--format", args->format,
                  "output format: gltf (NAME.gltf, .bin and PNG textures) or glb (one NAME.glb)")
      ->capture_default_str()
      ->check(CLI::IsMember({"gltf", "glb"}));
  cmd->add_option("--out", args->out, "output folder")->required();
  cmd->add_option("--name", args->name, "file and material name")->capture_default_str();
  cmd->callback([args] { finish(run_export(*args)); });
});

}  // namespace
}  // namespace vdrig::app

// `vdrig eval MAP --scene SCENE [--session S] [--out err.exr] [--json]`: the error of a fitted parameter map against
// the simulated scene's true radiance (pipeline/eval_stage.hpp), as a table per material or JSON.
#include <cstdio>
#include <string>

#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::app {
namespace {

struct EvalArgs {
  std::string map, scene, session, out;
  int directions = 1000;
  bool json = false;
};

Status run_eval(const EvalArgs& a) {
  auto map = fitting::ParameterMap::read(a.map);
  if (!map) return map.error();
  auto scene = sim::make_scene(a.scene);
  if (!scene) return scene.error();
  pipeline::EvalOptions options;
  options.dense_directions = a.directions;
  options.session_dir = a.session;
  // Progress on stdout, except when stdout is the JSON document.
  ProgressLine progress;
  if (!a.json)
    options.on_progress = [&progress](long done, long total) {
      progress.update(done, total, "  texels %ld/%ld", done, total);
    };
  auto report = pipeline::evaluate_map(*map, *scene, options);
  progress.finish();
  if (!report) return report.error();
  for (const std::string& warning : report->warnings) log::get("app")->warn("{}", warning);
  if (!a.out.empty()) VDRIG_TRY(write_exr(a.out, report->error_map));
  if (a.json)
    std::printf("%s\n", report->to_json().dump(2).c_str());
  else
    std::printf("%s", report->table().c_str());
  return Status::ok();
}

const CommandRegistrar kEval([](CLI::App& root) {
  auto args = std::make_shared<EvalArgs>();
  auto* cmd = root.add_subcommand("eval", "Error of a parameter map against a simulated scene's true radiance");
  cmd->add_option("map", args->map, "parameter map (EXR, vdrig fit)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--scene", args->scene, "the scene the map was captured from: a built-in name or a FILE.json")
      ->required();
  cmd->add_option("--session", args->session, "also evaluate over the directions this session's views sampled")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out,
                  "write the per-texel error map (OpenEXR: rel_rms, rel_rms.scaled, rel_rms.session, material)");
  cmd->add_option("--directions", args->directions, "dense directions on the upper hemisphere")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_flag("--json", args->json, "print the report as JSON");
  cmd->callback([args] { finish(run_eval(*args)); });
});

}  // namespace
}  // namespace vdrig::app

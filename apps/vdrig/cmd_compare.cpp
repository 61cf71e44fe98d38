// `vdrig compare S --maps a.exr,b.exr --views I,J|held-out [--json] [--out DIR] [--gamma G]`: fitted maps rendered
// at captured views beside the HDR photographs, with mean and standard deviation of |render - photo| over the
// diffuse and highlight pixels (pipeline/compare_stage.hpp).
#include <cstdio>
#include <string>
#include <vector>

#include "commands.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/pipeline/compare_stage.hpp"

namespace vdrig::app {
namespace {
namespace fs = std::filesystem;

struct CompareArgs {
  std::string session;
  std::vector<std::string> maps;
  std::vector<std::string> views;  // view numbers, or "held-out"
  bool holdout = false;            // deprecated spelling of --views held-out
  bool json = false;
  std::string out;
  double gamma = 1.0;
  double highlight_fraction = 0.1;
  std::string command;
};

/// A map given by its model spec ("phong:1") names SESSION/maps/phong:1.exr when no such file is in the working
/// folder.
fs::path resolve_map(const capture::Session& session, const std::string& name) {
  if (fs::exists(name) || name.find('/') != std::string::npos || name == "." || name == "..") return name;
  return session.layout().parameter_map_file(fs::path(name).extension() == ".exr" ? fs::path(name).stem().string()
                                                                                  : name);
}

Status run_compare(const CompareArgs& a) {
  auto session = capture::Session::open(a.session);
  if (!session) return session.error();
  std::vector<fs::path> maps;
  for (const auto& m : a.maps) maps.push_back(resolve_map(session.value(), m));
  // --views: numbers, or "held-out" (the views the maps' fits held out; --holdout is its deprecated spelling, kept
  // for scripts: --holdout is a count of views everywhere else).
  bool held_out = a.holdout;
  std::vector<int> views;
  for (const std::string& v : a.views) {
    if (v == "held-out") {
      held_out = true;
      continue;
    }
    size_t used = 0;
    int number = -1;
    try {
      number = std::stoi(v, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != v.size() || number < 0)
      return make_error(ErrorCode::kInvalidArgument,
                        "--views takes view numbers (from 0, as the console prints them) or held-out; got " + v);
    views.push_back(number);
  }
  if (held_out && !views.empty())
    return make_error(ErrorCode::kInvalidArgument, "--views: view numbers or held-out, not both");
  if (held_out) {
    // Every map must have held those views out: one fitted on them would be compared where it was fitted.
    auto held = pipeline::common_held_out_views(maps);
    if (!held) return held.error();
    views = held.value();
  }
  pipeline::CompareOptions options;
  options.gamma = a.gamma;
  options.highlight_fraction = a.highlight_fraction;
  options.out_dir = a.out;
  options.command = a.command;
  auto report = pipeline::compare_maps(session.value(), maps, views, options);
  if (!report) return report.error();
  if (a.json)
    std::printf("%s\n", report->to_json().dump(2).c_str());
  else
    std::printf("%simages and compare.json: %s\n", report->table().c_str(), report->json_file.parent_path().c_str());
  return Status::ok();
}

const CommandRegistrar kCompare([](CLI::App& root) {
  auto args = std::make_shared<CompareArgs>();
  auto* cmd = root.add_subcommand(
      "compare", "Render fitted maps at captured views beside the photographs: |render - photo| per region");
  cmd->add_option("session", args->session, "session folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--maps", args->maps, "parameter maps (EXR files, or model specs naming SESSION/maps/SPEC.exr)")
      ->required()
      ->delimiter(',');
  auto* views =
      cmd->add_option("--views", args->views,
                      "views to compare at: view numbers (from 0), e.g. 12,40, or held-out: the views the maps' fits "
                      "held out (vdrig fit --holdout N; every map must have held out the same)")
          ->delimiter(',');
  // Deprecated: --holdout is a count of held-out views in fit and demo; here it meant --views held-out.
  auto* holdout = cmd->add_flag("--holdout", args->holdout, "deprecated: --views held-out")->group("");
  holdout->excludes(views);
  cmd->add_option("--out", args->out, "output folder (default SESSION/renders/compare)");
  cmd->add_option("--gamma", args->gamma, "tone mapping y = 1 - exp(-gamma x) of render and photo")
      ->capture_default_str();
  cmd->add_option("--highlight", args->highlight_fraction,
                  "a pixel is highlight when the specular term exceeds this share of the total")
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "print the table as JSON");
  cmd->callback([args, views, holdout] {
    if (views->count() == 0 && holdout->count() == 0)
      finish(make_error(ErrorCode::kInvalidArgument, "name the views: --views I,J,... or --views held-out"));
    if (holdout->count() > 0)
      log::get("app")->warn("compare --holdout is deprecated: write --views held-out (--holdout is a count elsewhere)");
    args->command = "vdrig compare " + args->session + " --maps ";
    for (size_t i = 0; i < args->maps.size(); ++i) args->command += (i ? "," : "") + args->maps[i];
    for (size_t i = 0; i < args->views.size(); ++i) args->command += (i ? "," : " --views ") + args->views[i];
    if (args->holdout) args->command += " --views held-out";
    finish(run_compare(*args));
  });
});

}  // namespace
}  // namespace vdrig::app

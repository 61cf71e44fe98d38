// `vdrig report S --out report.html [--texel S,T ...] [--compare compare.json]`: one self-contained HTML page that
// shows a session (pipeline/report.hpp; docs/report.md).
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "commands.hpp"
#include "vdrig/pipeline/report.hpp"

namespace vdrig::app {
namespace {

struct ReportArgs {
  std::string session, out = "report.html", compare;
  std::vector<std::string> texels;
};

Status run_report(const ReportArgs& a) {
  pipeline::ReportOptions options;
  options.compare_json = a.compare;
  for (const std::string& texel : a.texels) {
    int s = 0, t = 0;
    char end = 0;
    if (std::sscanf(texel.c_str(), "%d,%d%c", &s, &t, &end) != 2)
      return make_error(ErrorCode::kInvalidArgument, "--texel wants S,T; got '" + texel + "'");
    options.texels.emplace_back(s, t);
  }
  const auto start = std::chrono::steady_clock::now();
  VDRIG_TRY(pipeline::write_report(a.session, a.out, options));
  std::printf("report: %s (%.2f s)\n", a.out.c_str(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return Status::ok();
}

const CommandRegistrar kReport([](CLI::App& root) {
  auto args = std::make_shared<ReportArgs>();
  auto* cmd = root.add_subcommand("report", "One self-contained HTML page showing a session (docs/report.md)");
  cmd->add_option("session", args->session, "session folder")->required();
  cmd->add_option("--out", args->out, "the HTML file to write")->capture_default_str();
  cmd->add_option("--texel", args->texels, "also plot texel S,T on the hemisphere (repeatable)");
  cmd->add_option("--compare", args->compare, "compare.json to show (default SESSION/renders/compare/compare.json)");
  cmd->callback([args] { finish(run_report(*args)); });
});

}  // namespace
}  // namespace vdrig::app

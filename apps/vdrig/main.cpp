#include <vector>

#include "commands.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::app {

static std::vector<CommandSetup>& registered() {
  static std::vector<CommandSetup> setups;
  return setups;
}

CommandRegistrar::CommandRegistrar(CommandSetup setup) { registered().push_back(std::move(setup)); }

void finish(const Status& status) {
  if (status) return;
  log::get("app")->error("{}", status.describe());
  throw CLI::RuntimeError(status.error().code == ErrorCode::kInvalidArgument ? kExitUsage : kExitFailure);
}

}  // namespace vdrig::app

int main(int argc, char** argv) {
  CLI::App app{"vdrig: capture how a surface looks from every direction, fit it, and play it back"};
  app.require_subcommand(1);
  std::string level = "info";
  app.add_option("--log-level", level, "trace, debug, info, warn, error, off")->capture_default_str();
  app.parse_complete_callback([&] { vdrig::log::set_level(level); });
  for (auto& setup : vdrig::app::registered()) setup(app);
  CLI11_PARSE(app, argc, argv);
  return 0;
}

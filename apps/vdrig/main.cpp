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

Result<std::pair<int, int>> parse_resolution(const std::string& r) {
  const auto x = r.find('x');
  try {
    if (x != std::string::npos) {
      size_t used_s = 0, used_t = 0;
      const int s = std::stoi(r.substr(0, x), &used_s), t = std::stoi(r.substr(x + 1), &used_t);
      if (used_s == x && used_t == r.size() - x - 1 && s >= 1 && t >= 1 && s <= 8192 && t <= 8192)
        return std::make_pair(s, t);
    }
  } catch (const std::exception&) {
  }
  return make_error(ErrorCode::kInvalidArgument, "--res must be SxT texels (1..8192 each), e.g. 256x256; got " + r);
}

}  // namespace vdrig::app

int main(int argc, char** argv) {
  CLI::App app{"vdrig: capture how a surface looks from every direction, fit it, and play it back"};
  app.require_subcommand(1);
  std::string level = "info";
  app.add_option("--log-level", level, vdrig::log::kLevelNames)->capture_default_str();
  app.parse_complete_callback([&] {
    // An unknown level would silence everything, errors included: refuse it as a usage error (exit 2).
    vdrig::app::finish(vdrig::log::set_level(level));
  });
  for (auto& setup : vdrig::app::registered()) setup(app);
  CLI11_PARSE(app, argc, argv);
  return 0;
}

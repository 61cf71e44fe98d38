#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli.hpp"
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

namespace {

/// Levenshtein distance: insertions, deletions and substitutions of one character each.
size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

}  // namespace

std::vector<std::string> flag_suggestions(const CLI::App& app, const std::vector<std::string>& args) {
  // The subcommand the arguments reached (the deepest parsed one): its options and its parents' are the valid ones.
  const CLI::App* reached = &app;
  for (auto subs = reached->get_subcommands(); !subs.empty(); subs = reached->get_subcommands()) reached = subs.front();
  std::vector<std::string> known, visible;  // every valid flag; those --help lists (never suggest a hidden alias)
  for (const CLI::App* a = reached; a != nullptr; a = a->get_parent())
    for (const CLI::Option* option : a->get_options())
      for (const std::string& name : option->get_lnames()) {
        known.push_back("--" + name);
        if (!option->get_group().empty()) visible.push_back("--" + name);
      }
  std::vector<std::string> out;
  for (const std::string& arg : args) {
    if (arg.rfind("--", 0) != 0 || arg.size() < 3) continue;
    const std::string flag = arg.substr(0, arg.find('='));
    if (std::find(known.begin(), known.end(), flag) != known.end()) continue;
    // Near enough to be a typo: at most 2 edits, and fewer than a third of the name (--res is not --out).
    const std::string* best = nullptr;
    size_t best_distance = 0;
    for (const std::string& name : visible) {
      const size_t d = edit_distance(flag, name);
      if (!best || d < best_distance) best = &name, best_distance = d;
    }
    if (best && best_distance <= std::min<size_t>(2, flag.size() / 3))
      out.push_back(flag + ": did you mean " + *best + "?");
  }
  return out;
}

}  // namespace vdrig::app

int vdrig::app::subcommand_index(int argc, char** argv) {
  // The root's only option with a value is --log-level (run_cli); anything else ends the root's options. C strings
  // only: vdrig calls this before the C++ runtime's initialisers have run (main.cpp).
  int i = 1;
  while (i < argc && (std::strcmp(argv[i], "--log-level") == 0 || std::strncmp(argv[i], "--log-level=", 12) == 0))
    i += std::strcmp(argv[i], "--log-level") == 0 ? 2 : 1;
  return std::min(i, argc);
}

int vdrig::app::run_cli(int argc, char** argv) {
  CLI::App app{"vdrig: capture how a surface looks from every direction, fit it, and play it back"};
  app.require_subcommand(1);
  std::string level = "info";
  app.add_option("--log-level", level, vdrig::log::kLevelNames)->capture_default_str();
  app.parse_complete_callback([&] {
    // An unknown level would silence everything, errors included: refuse it as a usage error (exit 2).
    vdrig::app::finish(vdrig::log::set_level(level));
  });
  for (auto& setup : vdrig::app::registered()) setup(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ExtrasError& e) {
    // CLI11 says only which arguments it did not expect; a mistyped flag (--modle) gets the nearest valid one.
    const int code = app.exit(e);
    for (const std::string& hint : vdrig::app::flag_suggestions(app, std::vector<std::string>(argv + 1, argv + argc)))
      std::fprintf(stderr, "%s\n", hint.c_str());
    return code;
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return 0;
}

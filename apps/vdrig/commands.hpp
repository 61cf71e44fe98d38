// The `vdrig` executable is a thin set of subcommands over the module libraries. Each cmd_*.cpp file adds its
// subcommands through a CommandRegistrar at static-initialisation time (safe here: these objects are linked
// directly into the executable, not pulled from a static library).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::app {

using CommandSetup = std::function<void(CLI::App& root)>;

struct CommandRegistrar {
  explicit CommandRegistrar(CommandSetup setup);
};

/// Exit codes shared by every subcommand.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // the work failed (device, I/O, data)
inline constexpr int kExitUsage = 2;    // bad arguments or configuration

/// Parses a texel resolution "SxT" (1..8192 each), e.g. "256x256"; kInvalidArgument with the reason otherwise.
Result<std::pair<int, int>> parse_resolution(const std::string& text);

/// For each argument of `args` that looks like a flag (--name or --name=value) but is none of the options of the
/// subcommand the parse of `app` reached (or of its parents), "--name: did you mean --nearest?" when a valid flag is
/// within 2 edits (and a third of its length). Called after CLI11 refused the arguments as unexpected.
std::vector<std::string> flag_suggestions(const CLI::App& app, const std::vector<std::string>& args);

/// Ends a subcommand: logs the error (if any) and throws CLI::RuntimeError with the matching exit code.
void finish(const Status& status);

}  // namespace vdrig::app

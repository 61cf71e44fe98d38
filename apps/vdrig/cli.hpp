// The command line both executables run: `vdrig` (every subcommand) and the thin `vdrig-rti` (rti only, issue #25:
// a process that maps only the libraries its command needs). Which subcommands exist is what the executable links
// (each cmd_*.cpp registers its own, commands.hpp), so the same argv gives the same help, errors and exit codes.
#pragma once

namespace vdrig::app {

/// Parses argv against the root (--log-level, then the registered subcommands) and runs the subcommand reached;
/// returns the process exit code (commands.hpp: kExitOk, kExitFailure, kExitUsage, or CLI11's parse codes).
int run_cli(int argc, char** argv);

/// Index in argv of the subcommand's name: the first argument after the root's --log-level (and its value), if
/// any; argc when there is none.
int subcommand_index(int argc, char** argv);

}  // namespace vdrig::app

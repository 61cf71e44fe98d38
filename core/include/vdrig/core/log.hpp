// One spdlog logger per module ("rig", "sim", "capture", "calib", "fitting", "viewer", "app").
#pragma once

#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::log {

/// The module's logger, created on first use (thread-safe), writing to stderr with the module's name.
std::shared_ptr<spdlog::logger> get(const std::string& module);

/// The level names set_level() accepts, comma-separated for messages: "trace, debug, info, warn, error, critical,
/// off".
extern const char* const kLevelNames;

/// Sets the level of every vdrig logger, present and future. An unknown name is kInvalidArgument listing
/// kLevelNames, and the level is left as it was (spdlog would read it as "off" and silence errors too).
Status set_level(const std::string& level);

}  // namespace vdrig::log

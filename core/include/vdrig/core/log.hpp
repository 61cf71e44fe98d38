// One spdlog logger per module ("rig", "sim", "capture", "calib", "fitting", "viewer", "app").
#pragma once

#include <spdlog/spdlog.h>

#include <memory>
#include <string>

namespace vdrig::log {

/// The module's logger, created on first use (thread-safe), writing to stderr with the module's name.
std::shared_ptr<spdlog::logger> get(const std::string& module);

/// Sets the level of every vdrig logger, present and future ("trace".."off").
void set_level(const std::string& level);

}  // namespace vdrig::log

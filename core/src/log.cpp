#include "vdrig/core/log.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>

#include <mutex>

namespace vdrig::log {
namespace {
std::mutex g_mutex;
spdlog::level::level_enum g_level = spdlog::level::info;
}  // namespace

std::shared_ptr<spdlog::logger> get(const std::string& module) {
  std::lock_guard lock(g_mutex);
  if (auto existing = spdlog::get(module)) return existing;
  auto logger = spdlog::stderr_color_mt(module);
  logger->set_level(g_level);
  logger->set_pattern("[%H:%M:%S.%e] [%n] [%^%l%$] %v");
  return logger;
}

const char* const kLevelNames = "trace, debug, info, warn, error, critical, off";

Status set_level(const std::string& level) {
  const spdlog::level::level_enum parsed = spdlog::level::from_str(level);
  // from_str maps every unknown name to off; only "off" itself means it.
  if (parsed == spdlog::level::off && level != "off")
    return make_error(ErrorCode::kInvalidArgument,
                      "unknown log level \"" + level + "\"; valid levels: " + std::string(kLevelNames));
  std::lock_guard lock(g_mutex);
  g_level = parsed;
  spdlog::apply_all([](const std::shared_ptr<spdlog::logger>& l) { l->set_level(g_level); });
  return Status::ok();
}

}  // namespace vdrig::log

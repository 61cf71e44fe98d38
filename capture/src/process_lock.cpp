#include "vdrig/capture/process_lock.hpp"

#include "vdrig/capture/session_layout.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;

Result<ProcessLock> lock_session(const fs::path& session_dir) {
  return ProcessLock::acquire(SessionLayout(session_dir).lock_file(), "session " + session_dir.string(),
                              ErrorCode::kInvalidArgument);
}

std::optional<std::string> rig_lock_name(const nlohmann::json& rig_config) {
  if (!rig_config.is_object()) return std::nullopt;
  const auto it = rig_config.find("lock");
  if (it == rig_config.end() || !it->is_string() || it->get<std::string>().empty()) return std::nullopt;
  return it->get<std::string>();
}

Result<std::optional<ProcessLock>> lock_rig(const nlohmann::json& rig_config) {
  const auto name = rig_lock_name(rig_config);
  if (!name) return std::optional<ProcessLock>();
  auto lock = lock_device("rig " + *name);
  if (!lock) return lock.error();
  return std::optional<ProcessLock>(std::move(lock.value()));
}

}  // namespace vdrig::capture

// The locks that guard a capture (docs/protocol.md, "Locks"), flock locks of core/process_lock.hpp:
//   - the session: SessionLayout::lock_file(), taken by whoever captures into the session (run_capture takes it for
//     the run unless the caller holds it; `vdrig capture --resume` and vdrigd take it before replaying the journal);
//   - the rig's devices: each hardware backend locks its device when it opens it (a serial port or GPIO chip on its
//     node, a Modbus TCP drive in core's device_lock_dir()), so building a rig another process drives fails with
//     kInUse naming that process, whatever runtime folder either was started with;
//   - a named rig: the config's top-level "lock" (lock_rig), for a rig whose devices do not lock themselves (a
//     camera alone, a simulated rig standing in for a bench), also in device_lock_dir().
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "vdrig/core/process_lock.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::capture {

using vdrig::ProcessLock;

/// Locks the session in `session_dir` for capturing (SessionLayout::lock_file()). Another process capturing:
/// kInvalidArgument "session DIR is in use by PID n" (the protocol's documented code for it).
Result<ProcessLock> lock_session(const std::filesystem::path& session_dir);

/// The config's top-level "lock" string, or nullopt (no "lock": the devices lock themselves, and a simulated rig
/// drives nothing).
std::optional<std::string> rig_lock_name(const nlohmann::json& rig_config);

/// Locks the rig named by the config's "lock" (lock_device("rig NAME"): kInUse "rig NAME is in use by PID n" when
/// another process holds it). nullopt (nothing held) for a config without "lock".
Result<std::optional<ProcessLock>> lock_rig(const nlohmann::json& rig_config);

}  // namespace vdrig::capture

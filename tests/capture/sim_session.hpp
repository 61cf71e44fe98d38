// Sessions and daemons on the capture tests' small simulated rig (test_support.hpp): a plan, a planned session
// written to a folder (no view captured yet), and the in-process vdrigd's configuration.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "test_support.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/plan.hpp"

namespace vdrig::capture::testing {

/// `scheme` with `bracket` planned for the simulated rig of `rig_config` (its stage's limits); no session written.
inline Result<Manifest> plan_sim(const nlohmann::json& rig_config, const std::string& scheme = "latlong:2",
                                 const std::string& bracket = "fixed:0.01") {
  auto rig = make_sim_rig(rig_config);
  if (!rig) return rig.error();
  PlanRequest req;
  req.rig_config = rig_config;
  req.scheme = scheme;
  req.bracket = bracket;
  req.stage = rig->stage->spec();
  return plan_manifest(req);
}

/// plan_sim's manifest, created as a session in `dir`.
inline Result<Manifest> create_sim_session(const std::filesystem::path& dir, const nlohmann::json& rig_config,
                                           const std::string& scheme = "latlong:2",
                                           const std::string& bracket = "fixed:0.01") {
  auto manifest = plan_sim(rig_config, scheme, bracket);
  if (!manifest) return manifest.error();
  auto session = Session::create(dir, manifest.value());
  if (!session) return session.error();
  return manifest;
}

/// vdrigd on small_sim_config(), its run and sessions folders in `root`, with no disk reserve.
inline DaemonConfig sim_daemon_config(const std::filesystem::path& root) {
  DaemonConfig config;
  config.runtime_dir = root / "run";
  config.sessions_dir = root / "sessions";
  config.rig_config = small_sim_config();
  config.make_rig = [](const nlohmann::json& rc) { return make_sim_rig(rc); };
  config.capture.disk_reserve_bytes = 0;
  return config;
}

}  // namespace vdrig::capture::testing

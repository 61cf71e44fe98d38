// A small simulated session with its HDR views merged (96 x 72 camera, latlong:2, two exposures): seconds to make,
// for tests that need a real session on disk.
#pragma once

#include <filesystem>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::pipeline::test {

inline Result<capture::Session> small_merged_session(const std::filesystem::path& out_dir) {
  CaptureRequest req;
  req.out_dir = out_dir;
  req.rig_config = sim::sim_rig_config({{"scene", "patchwork"}, {"camera", {{"width", 96}, {"height", 72}}}});
  req.scheme = "latlong:2";
  req.exposures_s = {1.0, 0.25};
  auto session = capture_session(req);
  if (!session) return session.error();
  VDRIG_TRY(merge_session_hdr(session.value()));
  return session;
}

}  // namespace vdrig::pipeline::test

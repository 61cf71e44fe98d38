// A small simulated session with its HDR views merged (96 x 72 camera, latlong:2, two exposures): seconds to make,
// for tests that need a real session on disk and are not about calibration: its calib/ is the simulator's truth
// (write_true_calibration).
#pragma once

#include <filesystem>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace vdrig::pipeline::test {

inline Result<capture::Session> small_merged_session(const std::filesystem::path& out_dir) {
  CaptureRequest req;
  req.out_dir = out_dir;
  req.rig_config = sim::sim_rig_config({{"scene", "patchwork"}, {"camera", {{"width", 96}, {"height", 72}}}});
  req.scheme = "latlong:2";
  req.exposures_s = {1.0, 0.25};
  auto session = capture_session(req);
  if (!session) return session.error();
  VDRIG_TRY(vdrig::test::write_true_calibration(session.value()));
  VDRIG_TRY(merge_session_hdr(session.value()));
  return session;
}

}  // namespace vdrig::pipeline::test

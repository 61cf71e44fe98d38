// write_true_calibration: a simulated session's calib/ folder written from the SIMULATOR'S TRUTH (camera, per-view
// poses, rig kinematics, response curve; pipeline::ground_truth_of), for tests that are not about calibration and
// need a session the stages accept. The pipeline never reads the truth itself (it wants calib/, as on a real rig);
// tests about calibration run the real calibration instead (pipeline::calibrate_session_*). Needs vdrig::pipeline.
#pragma once

#include <filesystem>
#include <string>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/calib/kinematic.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/pipeline/eval_stage.hpp"

namespace vdrig::test {

/// Writes SESSION/calib/camera.yml, views.json (every view at its true pose for its measured pan/tilt, the true
/// kinematics as the fit) and response.json from the simulator's configuration in the session's manifest.
/// kInvalidArgument for a session that is not simulated.
inline Status write_true_calibration(const capture::Session& session) {
  auto truth = pipeline::ground_truth_of(session.manifest().rig_config);
  if (!truth) return truth.error();
  if (!truth->has_value())
    return make_error(ErrorCode::kInvalidArgument, "session " + session.dir().string() + " is not simulated");
  const pipeline::GroundTruth& t = **truth;
  const capture::SessionLayout layout = session.layout();
  std::error_code ec;
  std::filesystem::create_directories(layout.calib_dir(), ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + layout.calib_dir().string() + ": " + ec.message());
  VDRIG_TRY(t.camera.save_yaml(layout.camera_file()));
  calib::ViewsFile views;
  views.camera_file = layout.camera_file().filename().string();
  views.layout = t.markers;
  for (const auto& view : session.manifest().views) {
    const auto frames = session.frames_of_view(view.index);
    calib::ViewRecord record;
    record.index = view.index;
    record.measured = frames.empty() ? view.target : frames.front().measured;
    calib::ViewExtrinsics extrinsics;
    extrinsics.pose = t.pose_at(record.measured);
    record.extrinsics = extrinsics;
    views.views.push_back(record);
  }
  calib::KinematicFit kinematics;
  kinematics.geometry = t.geometry;
  views.kinematics = kinematics.to_json();
  VDRIG_TRY(calib::write_views_json(layout.views_file(), views));
  return write_file_atomic(layout.response_file(), t.response.to_json().dump(1));
}

inline Status write_true_calibration(const std::filesystem::path& session_dir) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  return write_true_calibration(session.value());
}

}  // namespace vdrig::test

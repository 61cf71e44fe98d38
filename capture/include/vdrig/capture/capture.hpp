// Running a capture: drive the rig through a session's planned views, one exposure bracket per view, writing
// every frame through the Session (so an interrupted run resumes at the first incomplete view).
#pragma once

#include <atomic>
#include <functional>

#include "vdrig/capture/session.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::capture {

struct CaptureProgress {
  int views_done = 0;
  int views_total = 0;
  int view = -1;          // view in hand
  int bracket_index = 0;  // frame of the bracket in hand
  double elapsed_s = 0.0;
  double eta_s = 0.0;
};

struct CaptureOptions {
  std::vector<double> exposures_s;  // fixed bracket, longest first or any order; must be distinct and > 0
  double gain = 1.0;
  std::function<void(const CaptureProgress&)> on_progress;
  const std::atomic<bool>* stop_requested = nullptr;  // checked between frames: stop after the frame in hand

  bool is_valid(std::string* why) const;
};

/// Captures every view of the session's manifest that is not yet complete. Returns kCancelled when stopped on
/// request (the session stays consistent and resumable), or the first device/I-O failure.
Status run_capture(rig::Rig& rig, Session& session, const CaptureOptions& options);

/// True when any pixel of a camera frame is at the maximum code of its bit depth.
bool frame_saturated(const Frame& frame);

}  // namespace vdrig::capture

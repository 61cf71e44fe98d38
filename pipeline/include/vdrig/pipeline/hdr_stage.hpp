// HDR stage: each view's exposure bracket merged into one radiance image (capture::SessionLayout::hdr_file).
#pragma once

#include <functional>

#include "vdrig/calib/response_recovery.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

/// The session's response curve: SESSION/calib/response.json as radiometric calibration wrote it (never the
/// simulator's configuration); kNotFound naming `vdrig calib response SESSION` when there is none, kCorrupt for an
/// unreadable file.
Result<ResponseCurve> session_response(const capture::Session& session);

/// Radiometric calibration of a session from its own brackets: Debevec-Malik (calib::recover_response) on one
/// complete view's frames, written to SESSION/calib/response.json. view < 0 picks, among up to 16 complete views
/// spread over the session, the one whose frames cover the most codes (pixel values seen unclipped in some frame,
/// summed over the channels): the recovery sees the curve only where the bracket put codes.
struct ResponseCalibrationOptions {
  int view = -1;
  calib::ResponseRecoveryOptions recovery;
};
struct ResponseCalibration {
  int view = 0;           // the view whose bracket was used
  int codes_covered = 0;  // its code coverage (see above)
  calib::RecoveredResponse response;
};
Result<ResponseCalibration> calibrate_session_response(const capture::Session& session,
                                                       const ResponseCalibrationOptions& options = {});

struct HdrMergeOptions {
  /// Merge every complete view again, even those whose HDR image reads back fine.
  bool force = false;
  /// Called (from worker threads, one call at a time) after each view is merged or found current: `done` of the
  /// `total` views of the session; incomplete views count as done when skipped.
  std::function<void(int done, int total)> on_view;
};

/// What merge_session_hdr did, per view of the session.
struct HdrMergeSummary {
  int merged = 0;      // brackets merged now (new, damaged, or all of them with force)
  int current = 0;     // HDR images already there that read back fine, kept
  int incomplete = 0;  // views without a complete bracket, skipped
};

/// Merges every complete view's bracket into SESSION/hdr/view_VVVV.exr with session_response(). Views already
/// merged are skipped (resumable) unless options.force; an existing HDR image that does not read back (truncated,
/// damaged) is merged again, with a warning. Says how many views it merged and how many were current.
Result<HdrMergeSummary> merge_session_hdr(const capture::Session& session, const HdrMergeOptions& options = {});

}  // namespace vdrig::pipeline

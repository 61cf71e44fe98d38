// HDR stage: each view's exposure bracket merged into one radiance image (capture::SessionLayout::hdr_file).
#pragma once

#include "vdrig/capture/session.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

/// The session's response curve: SESSION/calib/response.json when radiometric calibration wrote it, else the
/// simulator's ground truth; kNotFound for an uncalibrated hardware session, kCorrupt for an unreadable file.
Result<ResponseCurve> session_response(const capture::Session& session);

struct HdrMergeOptions {
  /// Merge every complete view again, even those whose HDR image reads back fine.
  bool force = false;
};

/// Merges every complete view's bracket into SESSION/hdr/view_VVVV.exr with session_response(). Views already
/// merged are skipped (resumable) unless options.force; an existing HDR image that does not read back (truncated,
/// damaged) is merged again, with a warning.
Status merge_session_hdr(const capture::Session& session, const HdrMergeOptions& options = {});

}  // namespace vdrig::pipeline

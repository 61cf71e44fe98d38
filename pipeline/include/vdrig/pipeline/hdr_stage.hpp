// HDR stage: each view's exposure bracket merged into one radiance image (capture::SessionLayout::hdr_file).
#pragma once

#include "vdrig/capture/session.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

/// The session's response curve: SESSION/calib/response.json when radiometric calibration wrote it, else the
/// simulator's ground truth; kNotFound for an uncalibrated hardware session, kCorrupt for an unreadable file.
Result<ResponseCurve> session_response(const capture::Session& session);

/// Merges every complete view's bracket into SESSION/hdr/view_VVVV.exr with session_response(); views already
/// merged are skipped (resumable).
Status merge_session_hdr(const capture::Session& session);

}  // namespace vdrig::pipeline

// Running a capture: drive the rig through a session's planned views, one exposure bracket per view, writing
// every frame through the Session (so an interrupted run resumes at the first incomplete view).
//
// Never losing work: the journal is the truth (session.hpp). A view is committed (its frame lines and its completion
// line, in one journal append) only after all its frame files are durable; a stop (request, full disk, device fault,
// SIGKILL) at any point leaves the session resumable and run_capture on it again captures exactly the views not yet
// complete, each once.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>

#include "vdrig/capture/bracket.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::capture {

struct CaptureProgress {
  int views_done = 0;
  int views_total = 0;
  int view = -1;               // view in hand
  int bracket_index = 0;       // frame of the bracket in hand
  double exposure_s = 0;       // exposure of the frame just taken
  bool view_finished = false;  // true for the report after a view is marked complete, false for per-frame reports
  double elapsed_s = 0.0;
  double eta_s = 0.0;
};

/// Device faults (kDevice, kTimeout, kDisconnected) are retried this many times in all, sleeping
/// initial_backoff_s, 2x, 4x, ... (capped at max_backoff_s) between attempts; then the capture stops with the fault.
struct RetryPolicy {
  int max_attempts = 4;
  double initial_backoff_s = 0.05;
  double max_backoff_s = 2.0;
};

struct CaptureOptions {
  std::vector<double> exposures_s;     // fixed bracket (used when `bracket` is not set); distinct and > 0
  std::optional<BracketSpec> bracket;  // takes precedence over exposures_s
  double gain = 1.0;
  std::function<void(const CaptureProgress&)> on_progress;  // after every frame and after every completed view
  const std::atomic<bool>* stop_requested = nullptr;        // checked between frames: stop after the frame in hand
  /// Free space (bytes) that must remain on the session's file system after the next view's worst-case size; checked
  /// (statvfs) before each view. Below it the capture stops with kNoSpace before touching anything.
  uint64_t disk_reserve_bytes = 64ull << 20;
  RetryPolicy retry;

  bool is_valid(std::string* why) const;
  /// The bracket in effect (`bracket`, else fixed `exposures_s`).
  BracketSpec effective_bracket() const;
};

/// disk_reserve_bytes from a figure in MiB given by a user (--reserve-mb): a finite number in [0, 2^20] (1 TiB);
/// anything else, NaN and negatives included (which used to turn the disk check off), is kInvalidArgument.
Result<uint64_t> disk_reserve_bytes_from_mib(double mib);

/// Captures every view of the session's manifest that is not yet complete, in manifest order. The session is locked
/// for the run (process_lock.hpp) unless `session` holds its lock already; another process capturing it is
/// kInvalidArgument "session DIR is in use by PID n" before anything moves. Returns kCancelled
/// when stopped on request (the session stays consistent and resumable), kNoSpace when the disk is (nearly) full,
/// or the device/I-O failure that outlasted the retries. Warns (log and journal) when the camera is in auto exposure.
Status run_capture(rig::Rig& rig, Session& session, const CaptureOptions& options);

/// Homes the stage, runs run_capture and parks the axes at pan = tilt = 0 (when `park` is set), unless the capture
/// ended on a stage fault: then the axes stay where they are (parking would move the axis that still answers).
Status run_session(rig::Rig& rig, Session& session, const CaptureOptions& options, bool park = true);

/// True when any pixel of a camera frame is at the maximum code of its bit depth.
bool frame_saturated(const Frame& frame);

/// Bytes available to an unprivileged writer on the file system holding `path` (statvfs f_bavail * f_frsize).
Result<uint64_t> free_disk_bytes(const std::filesystem::path& path);

}  // namespace vdrig::capture

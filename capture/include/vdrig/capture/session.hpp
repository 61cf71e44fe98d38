// Session: one capture on disk, the unit every later stage reads. Where each file of the folder lives (frames,
// and what later stages add: hdr/, calib/, obsmap/, maps/, renders/) is SessionLayout's (session_layout.hpp).
//
//   SESSION/manifest.json   what was planned: format version, rig config, scheme, the planned views (direction,
//                           pan/tilt target) and exposures, software version. Written once, atomically.
//   SESSION/journal.jsonl   append-only JSON lines. A view's frames are committed together, once per view: every
//                           frame file of the bracket is fsync'd, the frames/ folder is fsync'd once, and only then
//                           the view's frame lines and its view_complete line are appended in ONE write() and the
//                           journal is fsync'd once. The journal is the truth: a view counts only once its
//                           view_complete line is durable, and that line is never written before every frame file
//                           of the view (data and folder entry) is durable. A frame file without a journal line is
//                           an interrupted view and is ignored (and overwritten when the view is captured again).
//                           Events (faults, pauses) are separate one-line appends.
//
//   Why this is as safe as journaling every frame (it was three fsyncs per frame; now one per frame file plus two
//   per view): a crash can only lose the view in hand, and that was already so, because a view without a durable
//   view_complete line is recaptured whole on resume (its journaled frames were never used). What a completed view
//   promises is unchanged: its frame files decode and hold what the lines say. A torn batch (crash mid-write) is
//   a torn last line plus complete frame lines without a view_complete: ignored on open. Readers never write: only
//   a writer holding the session's lock (capture, resume, `vdrig session check --repair`) cuts a torn last line off.
//   A view_redo line ({"type":"view_redo","view":V}) makes a complete view incomplete again (and voids its earlier
//   frame lines), so the next capture re-shoots it (`vdrig capture --resume S --redo V`, `vdrig session check
//   --repair`).
//
//   Hostile folders: sessions may live where other users can write. Files and folders below the session folder are
//   opened relative to their parent's descriptor with O_NOFOLLOW; a symbolic link at a file or folder vdrig reads or
//   writes (manifest.json, journal.jsonl, frames/ and its files, ...) is an error naming it, never followed.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/capture/process_lock.hpp"
#include "vdrig/capture/session_layout.hpp"
#include "vdrig/core/frame.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::capture {

inline constexpr int kSessionFormatVersion = 1;

/// One planned view: where the camera should look from (surface frame) and the stage target that gives it.
struct PlannedView {
  int index = 0;
  Vec3d direction = Vec3d::UnitZ();
  PanTilt target;
};

/// What the session intends to capture. Angles are stored in degrees in the JSON (an edge).
struct Manifest {
  int format_version = kSessionFormatVersion;
  std::string software_version;
  std::string created_utc;
  nlohmann::json rig_config;        // the rig config the session was started with
  std::string scheme;               // e.g. "latlong:6"
  std::string bracket;              // e.g. "fixed:0.01" or "auto"
  std::vector<double> exposures_s;  // for fixed brackets
  std::vector<PlannedView> views;
  double surface_width_mm = 1000.0;
  double surface_height_mm = 1000.0;
  nlohmann::json extra = nlohmann::json::object();  // stage-specific additions (kept on rewrite)

  nlohmann::json to_json() const;
  static Result<Manifest> from_json(const nlohmann::json& j);
};

/// A completed frame as recorded in the journal.
struct FrameRecord {
  int view = 0;
  int bracket_index = 0;
  std::string file;  // relative to the session folder
  double exposure_s = 0.0;
  double gain = 1.0;
  int bits = 8;
  PanTilt commanded;
  PanTilt measured;
  int64_t timestamp_ns = 0;
  uint64_t sequence = 0;
  bool saturated = false;  // any pixel at the maximum code (in the region of interest)

  nlohmann::json to_json() const;
  static Result<FrameRecord> from_json(const nlohmann::json& j);
};

class Session {
 public:
  /// Creates the folder (must not exist or be empty) and writes the manifest (which must plan at least one view).
  static Result<Session> create(const std::filesystem::path& dir, Manifest manifest);
  /// Opens an existing session; reads the manifest and replays the journal, writing nothing. A torn last journal
  /// line (a crash mid-append) is ignored with a warning and left in the file (repair_torn_journal() cuts it off,
  /// under the lock); any other malformed line is kCorrupt. A symbolic link at manifest.json or journal.jsonl is
  /// kInvalidArgument naming it.
  /// Journal lines naming a view outside the manifest (a negative, too large or non-integer "view", or a completion
  /// line without one) are ignored with a warning that says so. A manifest without views is kCorrupt.
  static Result<Session> open(const std::filesystem::path& dir);
  /// open() for capturing: takes the session's lock (lock()) before replaying the journal, so no other process
  /// appends while it is read, then cuts a torn last journal line off. The lock is held as long as this Session (or
  /// a copy) lives.
  static Result<Session> open_for_capture(const std::filesystem::path& dir);

  /// Locks the session for capturing (process_lock.hpp; SessionLayout::lock_file()) unless this Session holds the
  /// lock already, then repairs a torn journal tail. Another process capturing: kInvalidArgument "session DIR is in
  /// use by PID n".
  Status lock();
  /// Cuts a torn last journal line (a crash mid-append) off the file, so the next append starts a clean line. Only
  /// for a writer holding the session's lock: this Session's (locked()) or `held_lock`, the one run_capture takes;
  /// kInvalidArgument otherwise. Nothing to do: ok.
  Status repair_torn_journal(const ProcessLock* held_lock = nullptr);
  /// Whether the journal ended in a torn line when it was read (open_for_capture() has cut it off since).
  bool journal_torn() const { return journal_torn_when_read_; }
  /// What open() ignored in the journal, one message per line (a torn last line, lines naming no planned view).
  const std::vector<std::string>& journal_warnings() const { return journal_warnings_; }
  /// Marks complete views incomplete again so the next capture re-shoots them: removes their hdr/ files (made from
  /// the old frames), then appends one view_redo line per view with `reason` in one fsync'd write. Needs the lock
  /// (locked()); a view outside the manifest is kInvalidArgument and nothing is changed. Incomplete views are
  /// accepted (nothing to undo, the line is still written).
  Status mark_views_incomplete(const std::vector<int>& views, const std::string& reason);
  /// Whether this Session (or a copy) holds the session's lock.
  bool locked() const { return lock_ != nullptr; }

  const std::filesystem::path& dir() const { return dir_; }
  /// Where the session's files live.
  SessionLayout layout() const { return SessionLayout(dir_); }
  const Manifest& manifest() const { return manifest_; }
  const std::vector<FrameRecord>& frames() const { return frames_; }

  /// Frames of one view, in bracket order.
  std::vector<FrameRecord> frames_of_view(int view) const;
  /// Whether a view has all its frames (its journal has a "view complete" marker).
  bool view_complete(int view) const { return complete_views_.count(view) > 0; }
  int completed_view_count() const { return static_cast<int>(complete_views_.size()); }

  /// Writes the frame's image file (PNG) and queues its record for the view's commit. The file's data is not yet
  /// durable and the frame is not yet in frames() or the journal: mark_view_complete() commits the view. Frames of
  /// another view still queued (an abandoned attempt) are dropped; a frame of the same view and bracket replaces the
  /// queued one.
  Result<FrameRecord> append_frame(int view, int bracket_index, const Frame& frame, bool saturated);
  /// Commits a view: fsyncs every queued frame file of the view, then the frames/ folder, then appends the frame
  /// lines and the "view complete" line (number of frames of its bracket: brackets 0..frames-1; -1 = unknown, for
  /// old journals) in one write and fsyncs the journal. A view is only skipped on resume once it is complete. On
  /// failure nothing counts (the journal is cut back to its previous size) and the queue is kept, so the call can
  /// be repeated.
  Status mark_view_complete(int view, int frames = -1);
  /// Frames recorded by a view's completion marker (-1 when unknown or incomplete).
  int view_frame_count(int view) const;
  /// Appends an informational journal line ({"type": "event", ...}): faults, pauses, resumptions.
  Status append_event(const nlohmann::json& event);
  /// Adaptive sampling (adaptive.hpp): appends views chosen during the capture to the plan, in one fsync'd
  /// "views_planned" journal line carrying `info`; then manifest().views holds them (indices continue the plan),
  /// here and in every later open(). Needs the lock. The views are read back from the line's JSON, so this process
  /// aims exactly as a resumed one would.
  Status append_planned_views(const std::vector<PlannedView>& views, const nlohmann::json& info);
  /// Appends an "adaptive_stopped" line: adaptive sampling ended, `reason` says why. Needs the lock.
  Status append_adaptive_stop(const std::string& reason, const nlohmann::json& info);
  /// The journal's "views_planned" and "adaptive_stopped" lines, in order.
  const std::vector<nlohmann::json>& adaptive_lines() const { return adaptive_lines_; }

  /// Test/fault-injection hook called before every file write of the session (frame image; journal append: one per
  /// committed view and one per event) with the path about to be written; a failed Status is returned by that write as
  /// is (e.g. kNoSpace) and nothing is written. Empty by default.
  using WriteHook = std::function<Status(const std::filesystem::path&)>;
  void set_write_hook(WriteHook hook) { write_hook_ = std::move(hook); }
  /// Loads a recorded frame's pixels (error if missing or undecodable, or if a symbolic link is on its path inside
  /// the session).
  Result<cv::Mat> load_image(const FrameRecord& record) const;

  /// Rewrites the manifest's `extra` section atomically (stages record their settings there).
  Status update_extra(const nlohmann::json& extra);

 private:
  Session() = default;
  /// Appends `text` (whole lines) in one write() and fsyncs; on failure the journal is cut back to its old size.
  Status append_journal(const std::string& text);

  std::filesystem::path dir_;
  Manifest manifest_;
  std::vector<FrameRecord> frames_;
  std::map<int, int> complete_views_;  // view -> frame count (-1 unknown)
  std::vector<FrameRecord> pending_;   // frames of the view in hand: files written, not yet committed
  WriteHook write_hook_;
  std::shared_ptr<ProcessLock> lock_;  // held while capturing (shared by copies; released when the last goes)
  bool journal_torn_when_read_ = false;
  std::vector<std::string> journal_warnings_;
  std::vector<nlohmann::json> adaptive_lines_;
};

/// The software version written into manifests.
std::string software_version();

}  // namespace vdrig::capture

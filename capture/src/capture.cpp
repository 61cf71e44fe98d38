#include "vdrig/capture/capture.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <thread>

#include "vdrig/core/log.hpp"

namespace vdrig::capture {

bool CaptureOptions::is_valid(std::string* why) const {
  if (!(gain > 0)) {
    if (why) *why = "gain must be positive";
    return false;
  }
  if (retry.max_attempts < 1 || !(retry.initial_backoff_s >= 0) || !(retry.max_backoff_s >= 0)) {
    if (why) *why = "retry needs max_attempts >= 1 and non-negative backoffs";
    return false;
  }
  return effective_bracket().is_valid(why);
}

Result<uint64_t> disk_reserve_bytes_from_mib(double mib) {
  constexpr double kMaxMib = 1 << 20;
  if (!(mib >= 0 && mib <= kMaxMib))  // false for NaN too
    return make_error(ErrorCode::kInvalidArgument,
                      "--reserve-mb must be a number of MiB in [0, 1048576], got " + std::to_string(mib));
  return static_cast<uint64_t>(mib * 1024 * 1024);
}

BracketSpec CaptureOptions::effective_bracket() const {
  if (bracket) return *bracket;
  BracketSpec b;
  b.kind = BracketSpec::Kind::kFixed;
  b.exposures_s = exposures_s;
  return b;
}

bool frame_saturated(const Frame& frame) { return frame_saturated(frame, std::nullopt); }

Result<uint64_t> free_disk_bytes(const std::filesystem::path& path) {
  struct statvfs st {};
  if (::statvfs(path.c_str(), &st) != 0)
    return make_error(ErrorCode::kIo, "statvfs " + path.string() + ": " + std::strerror(errno));
  return static_cast<uint64_t>(st.f_bavail) * static_cast<uint64_t>(st.f_frsize);
}

namespace {

bool retryable(ErrorCode c) {
  return c == ErrorCode::kDevice || c == ErrorCode::kTimeout || c == ErrorCode::kDisconnected;
}

/// Runs `op` (returning Status or Result<T>) under the retry policy.
template <typename Op>
auto with_retry(const RetryPolicy& policy, const char* what, Op op) -> decltype(op()) {
  double backoff_s = policy.initial_backoff_s;
  for (int attempt = 1;; ++attempt) {
    auto r = op();
    if (r || !retryable(r.error().code) || attempt >= policy.max_attempts) {
      if (!r && retryable(r.error().code))
        log::get("capture")->error("{} failed {} times, giving up: {}", what, attempt, r.error().describe());
      return r;
    }
    log::get("capture")->warn("{} failed (attempt {}/{}): {}; retrying in {:.3f} s", what, attempt, policy.max_attempts,
                              r.error().describe(), backoff_s);
    std::this_thread::sleep_for(std::chrono::duration<double>(backoff_s));
    backoff_s = std::min(policy.max_backoff_s, backoff_s * 2.0);
  }
}

bool stop_now(const CaptureOptions& o) { return o.stop_requested && o.stop_requested->load(); }

}  // namespace

namespace {

/// run_capture; `stage_failed` (when not null) is set when a stage command (move, position) failed for good.
Status capture_views(rig::Rig& rig, Session& session, const CaptureOptions& options, bool* stage_failed) {
  std::string why;
  if (!options.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "capture options: " + why);
  // One capturer per session: a second process would drive its rig through the same views. Held for this run unless
  // the caller holds it already (Session::open_for_capture, Session::lock).
  std::optional<ProcessLock> run_lock;
  if (!session.locked()) {
    auto held = lock_session(session.dir());
    if (!held) return held.error();
    run_lock = std::move(held.value());
    // A torn last journal line (a crash mid-append) is cut off by the writer, under the lock: readers leave it.
    VDRIG_TRY(session.repair_torn_journal(&*run_lock));
  }
  auto logger = log::get("capture");
  BracketSpec bracket = options.effective_bracket();
  const auto& views = session.manifest().views;

  auto info = with_retry(options.retry, "camera info", [&] { return rig.camera->info(); });
  if (!info) return info.error();
  if (info->auto_exposure_on) {
    logger->warn("camera {} reports auto exposure/gain ON: bracket exposures will not be what is recorded",
                 info->model);
    (void)session.append_event({{"event", "warning"}, {"message", "camera auto exposure is on"}});
  }
  if (bracket.kind == BracketSpec::Kind::kAuto) {
    // The camera's range bounds the search; the spec's floor/ceiling stay the user's intent.
    bracket.ceiling_s = std::min(bracket.ceiling_s, info->max_exposure_s);
    bracket.floor_s = std::clamp(bracket.floor_s, info->min_exposure_s, bracket.ceiling_s);
  }
  // Worst case for one view: every frame as an uncompressed image.
  const uint64_t bytes_per_frame =
      static_cast<uint64_t>(std::max(info->width, 1)) * std::max(info->height, 1) * 3 * (info->bits > 8 ? 2 : 1);
  const uint64_t view_bytes = bytes_per_frame * static_cast<uint64_t>(bracket.max_frames()) + 4096;

  const auto start = std::chrono::steady_clock::now();
  CaptureProgress progress;
  progress.views_total = static_cast<int>(views.size());
  progress.views_done = session.completed_view_count();
  const int done_at_start = progress.views_done;
  auto report = [&](bool view_finished) {
    progress.view_finished = view_finished;
    progress.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const int done_now = progress.views_done - done_at_start;
    progress.eta_s = done_now > 0 ? progress.elapsed_s / done_now * (progress.views_total - progress.views_done) : 0.0;
    if (options.on_progress) options.on_progress(progress);
  };

  for (const PlannedView& view : views) {
    if (session.view_complete(view.index)) continue;
    if (stop_now(options)) return make_error(ErrorCode::kCancelled, "capture stopped");
    auto free_bytes = free_disk_bytes(session.dir());
    if (!free_bytes) return free_bytes.error();
    if (free_bytes.value() < options.disk_reserve_bytes + view_bytes)
      return make_error(ErrorCode::kNoSpace, "only " + std::to_string(free_bytes.value() >> 20) + " MiB free on " +
                                                 session.dir().string() + " (reserve " +
                                                 std::to_string(options.disk_reserve_bytes >> 20) +
                                                 " MiB + one view); free space and resume");
    progress.view = view.index;
    const Status moved = with_retry(options.retry, "stage move", [&] { return rig.stage->move_to(view.target); });
    auto measured = moved ? with_retry(options.retry, "stage position", [&] { return rig.stage->position(); })
                          : Result<PanTilt>(moved.error());
    if (!measured) {
      if (stage_failed) *stage_failed = true;
      return measured.error();
    }

    int frames = 0;
    double exposure_s = bracket.kind == BracketSpec::Kind::kFixed ? bracket.exposures_s[0] : bracket.ceiling_s;
    for (int b = 0;; ++b) {
      // A stop request between frames of a view leaves the view incomplete: it is redone whole on resume.
      if (b > 0 && stop_now(options)) return make_error(ErrorCode::kCancelled, "capture stopped mid-view");
      progress.bracket_index = b;
      VDRIG_TRY(with_retry(options.retry, "camera set_exposure",
                           [&] { return rig.camera->set_exposure(exposure_s, options.gain); }));
      auto frame = with_retry(options.retry, "camera capture", [&] { return rig.camera->capture(); });
      if (!frame) return frame.error();
      frame->commanded = view.target;
      frame->measured = measured.value();
      const bool saturated = frame_saturated(frame.value(), bracket.roi);
      auto record = session.append_frame(view.index, b, frame.value(), saturated);
      if (!record) return record.error();
      ++frames;
      progress.exposure_s = frame->exposure_s;
      report(false);
      if (bracket.kind == BracketSpec::Kind::kFixed) {
        if (frames >= static_cast<int>(bracket.exposures_s.size())) break;
        exposure_s = bracket.exposures_s[frames];
      } else {
        if (!saturated) break;
        if (exposure_s / 2.0 < bracket.floor_s * (1 - 1e-9)) {
          logger->warn("view {}: still saturated at the floor exposure {} s", view.index, exposure_s);
          break;
        }
        exposure_s /= 2.0;
      }
    }
    VDRIG_TRY(session.mark_view_complete(view.index, frames));
    ++progress.views_done;
    report(true);
    logger->debug("view {} done ({}/{}), {} frames", view.index, progress.views_done, progress.views_total, frames);
  }
  return Status::ok();
}

}  // namespace

Status run_capture(rig::Rig& rig, Session& session, const CaptureOptions& options) {
  return capture_views(rig, session, options, nullptr);
}

Status run_session(rig::Rig& rig, Session& session, const CaptureOptions& options, bool park) {
  VDRIG_TRY(with_retry(options.retry, "stage home", [&] { return rig.stage->home(); }));
  bool stage_failed = false;
  const Status s = capture_views(rig, session, options, &stage_failed);
  // After a stage fault (a stalled axis, a drive alarm) a park would move whichever axis still answers, into a rig
  // that may be jammed: the axes stay where they are, and the operator is told.
  if (park && stage_failed) {
    log::get("capture")->warn("not parking the axes: the stage failed ({}); they stay where they are",
                              s.error().message);
  } else if (park) {
    const Status p = rig.stage->move_to(PanTilt{0.0, 0.0});
    if (!p) log::get("capture")->warn("parking the axes failed: {}", p.describe());
  }
  if (!s) {
    (void)session.append_event(
        {{"event", "stopped"}, {"code", to_string(s.error().code)}, {"message", s.error().message}});
  }
  return s;
}

}  // namespace vdrig::capture

#include "vdrig/capture/capture.hpp"

#include <chrono>
#include <set>

#include "vdrig/core/log.hpp"

namespace vdrig::capture {

bool CaptureOptions::is_valid(std::string* why) const {
  if (exposures_s.empty()) {
    if (why) *why = "a bracket needs at least one exposure";
    return false;
  }
  std::set<double> seen;
  for (double e : exposures_s) {
    if (!(e > 0)) {
      if (why) *why = "exposures must be positive";
      return false;
    }
    if (!seen.insert(e).second) {
      if (why) *why = "duplicate exposure " + std::to_string(e) + " s in the bracket";
      return false;
    }
  }
  if (!(gain > 0)) {
    if (why) *why = "gain must be positive";
    return false;
  }
  return true;
}

bool frame_saturated(const Frame& frame) {
  double max_value = 0;
  cv::minMaxLoc(frame.image.reshape(1), nullptr, &max_value);
  return max_value >= (1 << frame.bits) - 1;
}

Status run_capture(rig::Rig& rig, Session& session, const CaptureOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "capture options: " + why);
  auto logger = log::get("capture");
  const auto& views = session.manifest().views;
  const auto start = std::chrono::steady_clock::now();
  CaptureProgress progress;
  progress.views_total = static_cast<int>(views.size());
  progress.views_done = session.completed_view_count();
  const int done_at_start = progress.views_done;
  for (const PlannedView& view : views) {
    if (session.view_complete(view.index)) continue;
    if (options.stop_requested && options.stop_requested->load()) return make_error(ErrorCode::kCancelled, "capture stopped");
    progress.view = view.index;
    VDRIG_TRY(rig.stage->move_to(view.target));
    auto measured = rig.stage->position();
    if (!measured) return measured.error();
    for (size_t b = 0; b < options.exposures_s.size(); ++b) {
      progress.bracket_index = static_cast<int>(b);
      VDRIG_TRY(rig.camera->set_exposure(options.exposures_s[b], options.gain));
      auto frame = rig.camera->capture();
      if (!frame) return frame.error();
      frame->commanded = view.target;
      frame->measured = measured.value();
      auto record = session.append_frame(view.index, static_cast<int>(b), frame.value(), frame_saturated(frame.value()));
      if (!record) return record.error();
    }
    VDRIG_TRY(session.mark_view_complete(view.index));
    ++progress.views_done;
    progress.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const int done_now = progress.views_done - done_at_start;
    progress.eta_s = done_now > 0 ? progress.elapsed_s / done_now * (progress.views_total - progress.views_done) : 0.0;
    if (options.on_progress) options.on_progress(progress);
    logger->debug("view {} done ({}/{})", view.index, progress.views_done, progress.views_total);
  }
  return Status::ok();
}

}  // namespace vdrig::capture

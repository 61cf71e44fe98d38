#include "vdrig/pipeline/hdr_stage.hpp"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

Result<ResponseCurve> session_response(const capture::Session& session) {
  const fs::path calibrated = session.layout().response_file();
  VDRIG_TRY(check_no_symlinks_below(session.dir(), calibrated));
  if (fs::exists(calibrated)) {
    auto j = read_json_file(calibrated);
    if (!j) return j.error();
    return ResponseCurve::from_json(j.value());
  }
  return make_error(ErrorCode::kNotFound, "session " + session.dir().string() + " has no response curve (" +
                                              calibrated.lexically_relative(session.dir()).string() +
                                              "): run `vdrig calib response " + session.dir().string() + "`");
}

namespace {

/// A view's bracket as Frames, sorted by effective exposure (what merge_hdr and recover_response want).
Result<std::vector<Frame>> load_view_frames(const capture::Session& session, int view) {
  std::vector<Frame> frames;
  for (const auto& rec : session.frames_of_view(view)) {
    auto img = session.load_image(rec);
    if (!img) return img.error();
    Frame f;
    f.image = img.value();
    f.exposure_s = rec.exposure_s;
    f.gain = rec.gain;
    f.bits = rec.bits;
    frames.push_back(std::move(f));
  }
  std::sort(frames.begin(), frames.end(),
            [](const Frame& a, const Frame& b) { return a.exposure_s * a.gain < b.exposure_s * b.gain; });
  return frames;
}

/// Codes seen unclipped (neither 0 nor the top code) in at least one frame, summed over the channels.
int codes_covered(const std::vector<Frame>& frames) {
  if (frames.empty()) return 0;
  const int levels = 1 << frames.front().bits;
  std::vector<std::vector<bool>> seen(3, std::vector<bool>(levels, false));
  for (const Frame& f : frames) {
    std::vector<cv::Mat> channels;
    cv::split(f.image, channels);
    for (size_t c = 0; c < channels.size() && c < 3; ++c) {
      cv::Mat as_int;
      channels[c].convertTo(as_int, CV_32S);
      for (auto it = as_int.begin<int>(); it != as_int.end<int>(); ++it)
        if (*it > 0 && *it < levels - 1) seen[c][*it] = true;
    }
  }
  int n = 0;
  for (const auto& channel : seen) n += static_cast<int>(std::count(channel.begin(), channel.end(), true));
  return n;
}

}  // namespace

Result<ResponseCalibration> calibrate_session_response(const capture::Session& session,
                                                       const ResponseCalibrationOptions& options) {
  auto logger = log::get("calib");
  std::vector<int> complete;
  for (const auto& view : session.manifest().views)
    if (session.view_complete(view.index)) complete.push_back(view.index);
  if (complete.empty())
    return make_error(ErrorCode::kNotFound, "session " + session.dir().string() + " has no complete view");
  std::vector<int> candidates;
  if (options.view >= 0) {
    if (std::find(complete.begin(), complete.end(), options.view) == complete.end())
      return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(options.view) + " is not complete");
    candidates = {options.view};
  } else {
    constexpr size_t kCandidates = 16;  // enough to find a view with dark and bright areas, without reading them all
    const size_t n = std::min(kCandidates, complete.size());
    for (size_t k = 0; k < n; ++k) candidates.push_back(complete[k * complete.size() / n]);
  }
  ResponseCalibration out;
  out.codes_covered = -1;
  std::vector<Frame> best;
  for (int v : candidates) {
    auto frames = load_view_frames(session, v);
    if (!frames) return frames.error();
    if (frames->size() < 2) continue;
    const int covered = codes_covered(frames.value());
    if (covered > out.codes_covered) {
      out.codes_covered = covered;
      out.view = v;
      best = std::move(frames.value());
    }
  }
  if (best.empty())
    return make_error(ErrorCode::kInvalidArgument,
                      "response recovery needs a bracket of at least two exposures; the session's views have one");
  auto recovered = calib::recover_response(best, options.recovery);
  if (!recovered) return recovered.error();
  out.response = std::move(recovered.value());
  const capture::SessionLayout layout = session.layout();
  VDRIG_TRY(check_no_symlinks_below(session.dir(), layout.response_file()));
  std::error_code ec;
  fs::create_directories(layout.calib_dir(), ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + layout.calib_dir().string() + ": " + ec.message());
  VDRIG_TRY(write_file_atomic(layout.response_file(), out.response.curve.to_json().dump(1)));
  logger->debug("response curve from view {} ({} codes covered) -> {}", out.view, out.codes_covered,
                layout.response_file().string());
  return out;
}

Result<HdrMergeSummary> merge_session_hdr(const capture::Session& session, const HdrMergeOptions& options) {
  auto response = session_response(session);
  if (!response) return response.error();
  const capture::SessionLayout layout = session.layout();
  // Sessions may sit in folders other users write to: a link planted at hdr/ (or at a file in it) would redirect
  // the EXRs. Refused here and again before each write (check_replaceable refuses a link at the file itself).
  VDRIG_TRY(check_no_symlinks_below(session.dir(), layout.hdr_dir()));
  std::error_code ec;
  fs::create_directories(layout.hdr_dir(), ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + layout.hdr_dir().string() + ": " + ec.message());
  const auto& views = session.manifest().views;
  std::atomic<size_t> next{0};
  std::mutex error_mutex;
  Status first_error;
  std::atomic<int> merged{0}, current{0}, incomplete{0};
  std::mutex progress_mutex;
  int done = 0;
  const auto view_done = [&] {
    std::lock_guard lock(progress_mutex);
    ++done;
    if (options.on_view) options.on_view(done, static_cast<int>(views.size()));
  };
  // One view: skipped when incomplete, kept when current, else merged; errors go to first_error.
  auto merge_view = [&](size_t i) {
    const int v = views[i].index;
    if (!session.view_complete(v)) {
      ++incomplete;
      return;
    }
    if (Status linked = check_no_symlinks_below(session.dir(), layout.hdr_file(v)); !linked) {
      std::lock_guard lock(error_mutex);
      if (first_error) first_error = linked;
      return;
    }
    if (!options.force && fs::exists(layout.hdr_file(v))) {
      auto existing = calib::read_hdr_exr(layout.hdr_file(v));
      if (existing) {
        ++current;
        return;
      }
      log::get("calib")->warn("view {}: {}; merging it again", v, existing.error().message);
    }
    const auto frames = load_view_frames(session, v);
    Status status = frames.status();
    if (status) {
      auto hdr = calib::merge_hdr(frames.value(), response.value());
      status = hdr ? calib::write_hdr_exr(layout.hdr_file(v), hdr.value(), ExrPixelType::kFloat) : hdr.status();
    }
    if (status) ++merged;
    if (!status) {
      std::lock_guard lock(error_mutex);
      if (first_error)
        first_error = make_error(status.error().code, "view " + std::to_string(v) + ": " + status.error().message);
    }
  };
  auto worker = [&] {
    for (size_t i = next++; i < views.size(); i = next++) {
      merge_view(i);
      view_done();
    }
  };
  std::vector<std::thread> pool;
  for (unsigned k = 0; k < std::max(1u, std::thread::hardware_concurrency()); ++k) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (!first_error) return first_error.error();
  return HdrMergeSummary{merged.load(), current.load(), incomplete.load()};
}

}  // namespace vdrig::pipeline

#include "vdrig/pipeline/hdr_stage.hpp"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <thread>

#include "ground_truth.hpp"
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
  auto truth = ground_truth_of(session.manifest().rig_config);
  if (!truth) return truth.error();
  if (!*truth)
    return make_error(ErrorCode::kNotFound, "no response curve: run radiometric calibration (" +
                                                calibrated.lexically_relative(session.dir()).string() + ")");
  return (*truth)->response;
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
    std::vector<Frame> frames;
    Status status;
    for (const auto& rec : session.frames_of_view(v)) {
      auto img = session.load_image(rec);
      if (!img) {
        status = img.error();
        break;
      }
      Frame f;
      f.image = img.value();
      f.exposure_s = rec.exposure_s;
      f.gain = rec.gain;
      f.bits = rec.bits;
      frames.push_back(std::move(f));
    }
    // The merge wants a monotonic bracket: sort by effective exposure.
    std::sort(frames.begin(), frames.end(),
              [](const Frame& a, const Frame& b) { return a.exposure_s * a.gain < b.exposure_s * b.gain; });
    if (status) {
      auto hdr = calib::merge_hdr(frames, response.value());
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

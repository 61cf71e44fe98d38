#include "still_camera.hpp"

#include <time.h>

#include <algorithm>
#include <cctype>
#include <cmath>

#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::rig {
namespace {

int64_t realtime_ns() {
  timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return static_cast<int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec;
}

}  // namespace

std::optional<size_t> nearest_stop(const std::vector<double>& values, double want) {
  if (!(want > 0.0) || !std::isfinite(want)) return std::nullopt;
  std::optional<size_t> best;
  double best_stops = 0.0;
  const double lw = std::log2(want);
  for (size_t i = 0; i < values.size(); ++i) {
    if (!(values[i] > 0.0) || !std::isfinite(values[i])) continue;
    const double stops = std::abs(std::log2(values[i]) - lw);
    if (!best || stops < best_stops) {
      best = i;
      best_stops = stops;
    }
  }
  return best;
}

bool is_decodable_image_name(const std::string& name) {
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string ext = name.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == "jpg" || ext == "jpeg" || ext == "jpe" || ext == "tif" || ext == "tiff" || ext == "png";
}

Status StillCamera::ensure_connected() {
  if (connected()) return Status::ok();
  VDRIG_TRY(connect());
  if (exposure_asked_) return apply_exposure();  // reconnected: the camera may have forgotten
  return Status::ok();
}

Result<CameraInfo> StillCamera::info() {
  VDRIG_TRY(ensure_connected());
  return info_;
}

Status StillCamera::set_exposure(double exposure_s, double gain) {
  if (!(exposure_s > 0.0) || !(gain > 0.0))
    return make_error(ErrorCode::kInvalidArgument, tag_ + ": exposure and gain must be positive");
  asked_ = {exposure_s, gain};
  exposure_asked_ = true;
  if (!connected()) VDRIG_TRY(connect());
  VDRIG_TRY(apply_exposure());
  if (std::abs(used_.exposure_s - exposure_s) > 0.01 * exposure_s)
    log::get("rig")->debug("{}: exposure {} s taken as {} s (the nearest stop the camera offers)", tag_, exposure_s,
                           used_.exposure_s);
  return Status::ok();
}

Result<Frame> StillCamera::capture() {
  VDRIG_TRY(ensure_connected());
  const int64_t t = realtime_ns();
  auto files = trigger();
  if (!files) return files.error();
  auto frame = collect(files.value());
  if (frame) frame->timestamp_ns = t;
  return frame;
}

Result<Frame> StillCamera::collect(const std::vector<StillFile>& files) {
  const auto chosen = std::find_if(files.begin(), files.end(), [](const StillFile& f) { return f.decodable; });
  const auto remove_all = [&] {
    if (keep_on_card_ || !can_remove()) return;
    for (const StillFile& f : files)
      if (Status s = remove(f); !s)
        log::get("rig")->warn("{}: cannot delete {} from the camera: {}", tag_, f.name, s.error().message);
  };
  if (chosen == files.end()) {
    std::string names;
    for (const StillFile& f : files) names += (names.empty() ? "" : ", ") + f.name;
    return make_error(ErrorCode::kUnsupported,
                      tag_ + ": the camera stored no JPEG/TIFF/PNG (" +
                          (names.empty() ? "no file" : names + ", left on the camera") +
                          "): RAW only? Set its image quality to JPEG (RAW+JPEG works too: the JPEG is used)");
  }
  auto bytes = download(*chosen);
  if (!bytes) return bytes.error();
  if (chosen->size_bytes != 0 && bytes->size() != chosen->size_bytes)
    return link_error(
        make_error(ErrorCode::kCorrupt, tag_ + ": " + chosen->name + ": " + std::to_string(bytes->size()) +
                                            " bytes where the camera said " + std::to_string(chosen->size_bytes)));
  // EXIF orientation is not applied (decode_image never does): the frame stays in sensor order.
  auto decoded = decode_image(std::string_view(reinterpret_cast<const char*>(bytes->data()), bytes->size()),
                              chosen->name, ImageDecode::kBgr8);
  // Deleted only once decoded: a photo that does not decode (or does not arrive whole) stays on the camera.
  if (!decoded)
    return make_error(ErrorCode::kCorrupt, tag_ + ": " + chosen->name + " (" + std::to_string(bytes->size()) +
                                               " bytes) does not decode (" + decoded.error().message +
                                               "); left on the camera");
  cv::Mat image = std::move(decoded.value());
  remove_all();
  info_.width = image.cols;
  info_.height = image.rows;
  Frame f;
  f.image = std::move(image);
  f.exposure_s = used_.exposure_s;
  f.gain = used_.gain;
  f.bits = 8;
  f.sequence = captures_++;
  return f;
}

}  // namespace vdrig::rig

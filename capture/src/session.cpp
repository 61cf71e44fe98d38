#include "vdrig/capture/session.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <type_traits>

#include "vdrig/core/file_io.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;
using nlohmann::json;

std::string software_version() { return "vdrig 0.1.0"; }

namespace {

json pan_tilt_json(const PanTilt& p) {
  return {{"pan_deg", rad_to_deg(p.pan_rad)}, {"tilt_deg", rad_to_deg(p.tilt_rad)}};
}
/// `v` as an Int, or a json::type_error naming `key` (caught with the other json errors of the readers below):
/// nlohmann's get<int>() casts a float such as 1e30 or a wider integer unchecked, which is undefined behaviour.
template <typename Int>
Int checked_int(const json& v, const char* key) {
  using Limits = std::numeric_limits<Int>;
  bool fits = false;
  if (v.is_number_unsigned()) {
    fits = v.get<uint64_t>() <= static_cast<uint64_t>(Limits::max());
  } else if (v.is_number_integer()) {
    const int64_t i = v.get<int64_t>();
    fits = i >= 0 ? static_cast<uint64_t>(i) <= static_cast<uint64_t>(Limits::max())
                  : std::is_signed_v<Int> && i >= static_cast<int64_t>(Limits::min());
  }
  if (!fits)
    throw json::type_error::create(302,
                                   std::string("\"") + key + "\" must be an integer that fits, not " +
                                       (v.is_number() ? v.dump() : std::string("a ") + v.type_name()),
                                   &v);
  return v.get<Int>();
}
/// Field `key` of object `j` as an Int (checked_int), or `fallback` when absent.
template <typename Int>
Int int_or(const json& j, const char* key, Int fallback) {
  const auto it = j.find(key);
  return it == j.end() ? fallback : checked_int<Int>(*it, key);
}

PanTilt pan_tilt_from(const json& j) {
  return {deg_to_rad(j.at("pan_deg").get<double>()), deg_to_rad(j.at("tilt_deg").get<double>())};
}

/// Whether a journal line's "view" is a number that names no view of the manifest (99999, -1, 1e30, 2.5): such a
/// line is ignored. A missing or non-number "view" is left to the line's parser.
bool view_out_of_range(const json& line, size_t view_count) {
  const auto it = line.find("view");
  if (it == line.end() || !it->is_number()) return false;
  if (it->is_number_unsigned()) return it->get<uint64_t>() >= view_count;
  if (it->is_number_integer()) return it->get<int64_t>() < 0 || static_cast<uint64_t>(it->get<int64_t>()) >= view_count;
  return true;  // a floating-point view index
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

json Manifest::to_json() const {
  json views_json = json::array();
  for (const auto& v : views) {
    const SphericalDir s = spherical_from_direction(v.direction);
    views_json.push_back({{"index", v.index},
                          {"direction", {v.direction.x(), v.direction.y(), v.direction.z()}},
                          {"azimuth_deg", rad_to_deg(s.azimuth_rad)},
                          {"zenith_deg", rad_to_deg(s.zenith_rad)},
                          {"target", pan_tilt_json(v.target)}});
  }
  return {{"format", "vdrig-session"},
          {"format_version", format_version},
          {"software_version", software_version},
          {"created_utc", created_utc},
          {"rig_config", rig_config},
          {"scheme", scheme},
          {"bracket", bracket},
          {"exposures_s", exposures_s},
          {"surface_size_mm", {surface_width_mm, surface_height_mm}},
          {"views", views_json},
          {"extra", extra}};
}

Result<Manifest> Manifest::from_json(const json& j) {
  try {
    if (j.value("format", "") != "vdrig-session")
      return make_error(ErrorCode::kCorrupt, "manifest: not a vdrig session manifest");
    Manifest m;
    m.format_version = checked_int<int>(j.at("format_version"), "format_version");
    if (m.format_version != kSessionFormatVersion)
      return make_error(ErrorCode::kCorrupt,
                        "manifest: unsupported format_version " + std::to_string(m.format_version));
    m.software_version = j.value("software_version", "");
    m.created_utc = j.value("created_utc", "");
    m.rig_config = j.value("rig_config", json::object());
    m.scheme = j.value("scheme", "");
    m.bracket = j.value("bracket", "");
    m.exposures_s = j.value("exposures_s", std::vector<double>{});
    const auto size = j.at("surface_size_mm");
    m.surface_width_mm = size.at(0).get<double>();
    m.surface_height_mm = size.at(1).get<double>();
    for (const auto& v : j.at("views")) {
      PlannedView pv;
      pv.index = checked_int<int>(v.at("index"), "index");
      const auto d = v.at("direction");
      pv.direction = Vec3d(d.at(0).get<double>(), d.at(1).get<double>(), d.at(2).get<double>());
      pv.target = pan_tilt_from(v.at("target"));
      if (pv.index != static_cast<int>(m.views.size()))
        return make_error(ErrorCode::kCorrupt, "manifest: views must be indexed 0..N-1 in order");
      m.views.push_back(pv);
    }
    if (m.views.empty()) return make_error(ErrorCode::kCorrupt, "manifest: no views planned");
    m.extra = j.value("extra", json::object());
    return m;
  } catch (const json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("manifest: ") + e.what());
  }
}

json FrameRecord::to_json() const {
  return {{"type", "frame"},
          {"view", view},
          {"bracket", bracket_index},
          {"file", file},
          {"exposure_s", exposure_s},
          {"gain", gain},
          {"bits", bits},
          {"commanded", pan_tilt_json(commanded)},
          {"measured", pan_tilt_json(measured)},
          {"timestamp_ns", timestamp_ns},
          {"sequence", sequence},
          {"saturated", saturated}};
}

Result<FrameRecord> FrameRecord::from_json(const json& j) {
  try {
    FrameRecord r;
    r.view = checked_int<int>(j.at("view"), "view");
    r.bracket_index = checked_int<int>(j.at("bracket"), "bracket");
    r.file = j.at("file").get<std::string>();
    r.exposure_s = j.at("exposure_s").get<double>();
    r.gain = j.value("gain", 1.0);
    r.bits = int_or(j, "bits", 8);
    r.commanded = pan_tilt_from(j.at("commanded"));
    r.measured = pan_tilt_from(j.at("measured"));
    r.timestamp_ns = int_or(j, "timestamp_ns", int64_t{0});
    r.sequence = int_or(j, "sequence", uint64_t{0});
    r.saturated = j.value("saturated", false);
    if (r.file.find("..") != std::string::npos || r.file.empty() || r.file[0] == '/')
      return make_error(ErrorCode::kCorrupt, "journal: frame file name escapes the session: " + r.file);
    return r;
  } catch (const json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("journal frame: ") + e.what());
  }
}

Result<Session> Session::create(const fs::path& dir, Manifest manifest) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_empty(dir, ec))
    return make_error(ErrorCode::kInvalidArgument, "session folder " + dir.string() + " exists and is not empty");
  if (manifest.views.empty()) return make_error(ErrorCode::kInvalidArgument, "a session needs at least one view");
  const SessionLayout layout(dir);
  fs::create_directories(layout.frames_dir(), ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + dir.string() + ": " + ec.message());
  if (manifest.software_version.empty()) manifest.software_version = software_version();
  if (manifest.created_utc.empty()) manifest.created_utc = utc_now();
  VDRIG_TRY(write_file_atomic(layout.manifest_file(), manifest.to_json().dump(2) + "\n"));
  VDRIG_TRY(write_file_atomic(layout.journal_file(), ""));
  Session s;
  s.dir_ = dir;
  s.manifest_ = std::move(manifest);
  return s;
}

Result<Session> Session::open(const fs::path& dir) {
  const SessionLayout layout(dir);
  const fs::path manifest_path = layout.manifest_file();
  if (!fs::exists(manifest_path)) return make_error(ErrorCode::kNotFound, "no session at " + dir.string());
  Session s;
  s.dir_ = dir;
  {
    auto j = read_json_file(manifest_path);
    if (!j) return j.error();
    auto m = Manifest::from_json(j.value());
    if (!m) return make_error(ErrorCode::kCorrupt, manifest_path.string() + ": " + m.error().message);
    s.manifest_ = std::move(m.value());
  }
  std::ifstream journal(layout.journal_file(), std::ios::binary);
  if (!journal)
    return make_error(ErrorCode::kCorrupt,
                      "session " + dir.string() + " has no " + layout.journal_file().filename().string());
  std::stringstream buf;
  buf << journal.rdbuf();
  const std::string text = buf.str();
  size_t pos = 0;
  int line_no = 0;
  while (pos < text.size()) {
    const size_t end = text.find('\n', pos);
    ++line_no;
    if (end == std::string::npos) {
      // No newline: the process died while appending this line. It was never acknowledged; drop it.
      log::get("capture")->warn("session {}: dropping torn last journal line {}", dir.string(), line_no);
      // Cut it off, or the next append would glue a new line onto it and corrupt the journal.
      std::error_code ec;
      fs::resize_file(layout.journal_file(), pos, ec);
      if (ec) return make_error(ErrorCode::kIo, "cannot truncate torn journal line: " + ec.message());
      break;
    }
    const std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    if (line.empty()) continue;
    json j = json::parse(line, nullptr, false);
    if (j.is_discarded())
      return make_error(ErrorCode::kCorrupt, "journal line " + std::to_string(line_no) + " is not valid JSON");
    const std::string where = "journal line " + std::to_string(line_no);
    if (!j.is_object()) return make_error(ErrorCode::kCorrupt, where + " is not a JSON object");
    const auto type_field = j.find("type");
    if (type_field != j.end() && !type_field->is_string())
      return make_error(ErrorCode::kCorrupt, where + ": \"type\" must be a string");
    const std::string type = type_field == j.end() ? "" : type_field->get<std::string>();
    if (type == "frame" || type == "view_complete") {
      // A completion line must name its view (the old default -1 counted a view that does not exist).
      if (view_out_of_range(j, s.manifest_.views.size()) || (type == "view_complete" && !j.contains("view"))) {
        log::get("capture")->warn("session {}: journal line {} names view {}, outside the manifest's {} views: ignored",
                                  dir.string(), line_no, j.value("view", json()).dump(), s.manifest_.views.size());
        continue;
      }
    }
    if (type == "frame") {
      auto r = FrameRecord::from_json(j);
      if (!r) return make_error(ErrorCode::kCorrupt, where + ": " + r.error().message);
      s.frames_.push_back(r.value());
    } else if (type == "view_complete") {
      try {
        s.complete_views_[int_or(j, "view", -1)] = int_or(j, "frames", -1);
      } catch (const json::exception& e) {
        return make_error(ErrorCode::kCorrupt, where + ": " + e.what());
      }
    }  // other types (events, faults) are informational
  }
  return s;
}

Result<Session> Session::open_for_capture(const fs::path& dir) {
  if (!fs::exists(SessionLayout(dir).manifest_file()))
    return make_error(ErrorCode::kNotFound, "no session at " + dir.string());
  auto lock = lock_session(dir);
  if (!lock) return lock.error();
  auto s = open(dir);
  if (!s) return s.error();
  s->lock_ = std::make_shared<ProcessLock>(std::move(lock.value()));
  return s;
}

Status Session::lock() {
  if (lock_) return Status::ok();
  auto lock = lock_session(dir_);
  if (!lock) return lock.error();
  lock_ = std::make_shared<ProcessLock>(std::move(lock.value()));
  return Status::ok();
}

std::vector<FrameRecord> Session::frames_of_view(int view) const {
  std::vector<FrameRecord> out;
  for (const auto& f : frames_)
    if (f.view == view) out.push_back(f);
  // A resumed view may have frames of an interrupted attempt before its complete set: keep the last per bracket,
  // and only the brackets its completion marker counts (an auto bracket of an interrupted attempt may differ).
  const int count = view_frame_count(view);
  std::map<int, FrameRecord> last;
  for (const auto& f : out)
    if (count < 0 || f.bracket_index < count) last[f.bracket_index] = f;
  out.clear();
  for (auto& [k, f] : last) out.push_back(f);
  return out;
}

namespace {

/// Writes `bytes` to `path` (created or truncated) and starts its writeback without waiting for it, so the disk
/// works while the next frame is being taken; durability comes later from fsync_path().
Status write_frame_file(const fs::path& path, const std::vector<uchar>& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return error_from_errno(errno, "create " + path.string());
  if (const int err = write_all(fd, bytes.data(), bytes.size()); err != 0) {
    ::close(fd);
    return error_from_errno(err, "write " + path.string());
  }
  // Only a hint (an error here resurfaces at fsync): queue the pages for writeback now.
  (void)::sync_file_range(fd, 0, 0, SYNC_FILE_RANGE_WRITE);
  if (::close(fd) != 0) return error_from_errno(errno, "close " + path.string());
  return Status::ok();
}

}  // namespace

Status Session::append_journal(const std::string& text) {
  const fs::path path = layout().journal_file();
  if (write_hook_) VDRIG_TRY(write_hook_(path));
  const int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd < 0) return make_error(ErrorCode::kIo, "open " + path.string() + ": " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    return make_error(ErrorCode::kIo, "stat " + path.string() + ": " + std::strerror(err));
  }
  // One write() to an O_APPEND file; a crash leaves at most a torn last line (dropped on open).
  const ssize_t n = ::write(fd, text.data(), text.size());
  const int write_errno = errno;
  const int rc = n == static_cast<ssize_t>(text.size()) ? ::fsync(fd) : -1;
  const int sync_errno = errno;
  if (rc != 0) {
    // Whatever part did land must not count (nor glue onto the next append): cut it off again.
    if (::ftruncate(fd, st.st_size) == 0) (void)::fsync(fd);
  }
  ::close(fd);
  if (n != static_cast<ssize_t>(text.size())) {
    const int err = n < 0 ? write_errno : ENOSPC;  // a short write to a regular file means the disk is full
    return error_from_errno(err, "append to journal");
  }
  if (rc != 0) return error_from_errno(sync_errno, "fsync journal");
  return Status::ok();
}

Result<FrameRecord> Session::append_frame(int view, int bracket_index, const Frame& frame, bool saturated) {
  if (frame.image.empty()) return make_error(ErrorCode::kInvalidArgument, "empty frame image");
  if (frame.image.depth() != CV_8U && frame.image.depth() != CV_16U)
    return make_error(ErrorCode::kInvalidArgument, "frame image must be 8- or 16-bit");
  const std::string name = SessionLayout::frame_file_relative(view, bracket_index).string();
  std::vector<uchar> bytes;
  try {
    // Speed over size (encoding is the daemon's main per-frame CPU cost): OpenCV's fast path is zlib level 1 with
    // the RLE strategy and the SUB filter only; naming a compression level instead makes libpng try every filter on
    // every row, about twice as slow for files ~15% smaller.
    if (!cv::imencode(".png", frame.image, bytes, {cv::IMWRITE_PNG_STRATEGY, cv::IMWRITE_PNG_STRATEGY_RLE}))
      return make_error(ErrorCode::kIo, std::string("PNG encoding failed for ") + name);
  } catch (const cv::Exception& e) {
    return make_error(ErrorCode::kIo, std::string("PNG encoding failed for ") + name + ": " + e.what());
  }
  if (write_hook_) VDRIG_TRY(write_hook_(dir_ / name));
  // No temporary + rename: until the view's commit no journal line names this file, so a torn file is never read.
  VDRIG_TRY(write_frame_file(dir_ / name, bytes));
  FrameRecord r;
  r.view = view;
  r.bracket_index = bracket_index;
  r.file = name;
  r.exposure_s = frame.exposure_s;
  r.gain = frame.gain;
  r.bits = frame.bits;
  r.commanded = frame.commanded;
  r.measured = frame.measured;
  r.timestamp_ns = frame.timestamp_ns;
  r.sequence = frame.sequence;
  r.saturated = saturated;
  std::erase_if(pending_, [&](const FrameRecord& p) { return p.view != view || p.bracket_index == bracket_index; });
  pending_.push_back(r);
  return r;
}

Status Session::mark_view_complete(int view, int frames) {
  std::vector<FrameRecord> batch;
  for (const auto& p : pending_)
    if (p.view == view && (frames < 0 || p.bracket_index < frames)) batch.push_back(p);
  if (!batch.empty()) {
    // Data first, then the names, then the line that makes them count.
    for (const auto& r : batch) VDRIG_TRY(fsync_path(dir_ / r.file, false));
    VDRIG_TRY(fsync_path(layout().frames_dir(), true));
  }
  std::string text;
  for (const auto& r : batch) text += r.to_json().dump() + "\n";
  json line = {{"type", "view_complete"}, {"view", view}};
  if (frames >= 0) line["frames"] = frames;
  text += line.dump() + "\n";
  VDRIG_TRY(append_journal(text));
  frames_.insert(frames_.end(), batch.begin(), batch.end());
  std::erase_if(pending_, [&](const FrameRecord& p) { return p.view == view; });
  complete_views_[view] = frames;
  return Status::ok();
}

int Session::view_frame_count(int view) const {
  const auto it = complete_views_.find(view);
  return it == complete_views_.end() ? -1 : it->second;
}

Status Session::append_event(const json& event) {
  json line = event;
  line["type"] = "event";
  line["utc"] = utc_now();
  return append_journal(line.dump() + "\n");
}

Result<cv::Mat> Session::load_image(const FrameRecord& record) const { return read_png(dir_ / record.file); }

Status Session::update_extra(const json& extra) {
  manifest_.extra = extra;
  return write_file_atomic(layout().manifest_file(), manifest_.to_json().dump(2) + "\n");
}

}  // namespace vdrig::capture

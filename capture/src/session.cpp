#include "vdrig/capture/session.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <limits>
#include <type_traits>

#include "session_files.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_codec.hpp"
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

/// A planned view as the manifest (and a views_planned journal line) writes it.
PlannedView planned_view_from(const json& v) {
  PlannedView pv;
  pv.index = checked_int<int>(v.at("index"), "index");
  const auto d = v.at("direction");
  pv.direction = Vec3d(d.at(0).get<double>(), d.at(1).get<double>(), d.at(2).get<double>());
  pv.target = pan_tilt_from(v.at("target"));
  return pv;
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
      const PlannedView pv = planned_view_from(v);
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
  Session s;
  s.dir_ = dir;
  {
    // Read without following links (session_files.hpp): a manifest linked to another session's is refused.
    auto text = detail::read_session_file(dir, manifest_path.filename(), kMaxJsonFileBytes);
    if (!text) {
      if (text.error().code == ErrorCode::kNotFound)
        return make_error(ErrorCode::kNotFound, "no session at " + dir.string());
      return text.error();
    }
    json j = json::parse(text.value(), nullptr, false);
    if (j.is_discarded() || !j.is_object())
      return make_error(ErrorCode::kCorrupt, manifest_path.string() + ": not a JSON object");
    auto m = Manifest::from_json(j);
    if (!m) return make_error(ErrorCode::kCorrupt, manifest_path.string() + ": " + m.error().message);
    s.manifest_ = std::move(m.value());
  }
  constexpr std::size_t kMaxJournalBytes = std::size_t{1} << 30;
  auto journal = detail::read_session_file(dir, layout.journal_file().filename(), kMaxJournalBytes);
  if (!journal) {
    if (journal.error().code == ErrorCode::kNotFound)
      return make_error(ErrorCode::kCorrupt,
                        "session " + dir.string() + " has no " + layout.journal_file().filename().string());
    return journal.error();
  }
  const std::string& text = journal.value();
  size_t pos = 0;
  int line_no = 0;
  while (pos < text.size()) {
    const size_t end = text.find('\n', pos);
    ++line_no;
    if (end == std::string::npos) {
      // No newline: the process died while appending this line. It was never acknowledged; ignore it. A reader
      // leaves the file alone: only a writer holding the lock cuts it off (repair_torn_journal).
      const std::string warning = layout.journal_file().string() + ": torn last line " + std::to_string(line_no) +
                                  " (a crash mid-append) ignored; the next capture or `vdrig session check --repair` "
                                  "cuts it off";
      log::get("capture")->warn("session {}: {}", dir.string(), warning);
      s.journal_warnings_.push_back(warning);
      s.journal_torn_when_read_ = true;
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
    if (type == "frame" || type == "view_complete" || type == "view_redo") {
      // A completion line must name its view (the old default -1 counted a view that does not exist).
      if (view_out_of_range(j, s.manifest_.views.size()) || (type != "frame" && !j.contains("view"))) {
        const std::string warning = "journal line " + std::to_string(line_no) + " names view " +
                                    j.value("view", json()).dump() + ", outside the manifest's " +
                                    std::to_string(s.manifest_.views.size()) + " views: ignored";
        log::get("capture")->warn("session {}: {}", dir.string(), warning);
        s.journal_warnings_.push_back(warning);
        continue;
      }
    }
    if (type == "views_planned") {
      // Views planned during an adaptive capture: they extend the plan, unless a rewritten manifest holds them.
      try {
        const int first = checked_int<int>(j.at("first_view"), "first_view");
        const auto& list = j.at("views");
        if (first < 0 || first > static_cast<int>(s.manifest_.views.size()))
          return make_error(ErrorCode::kCorrupt, where + ": first_view " + std::to_string(first) + " leaves a gap");
        for (size_t k = 0; k < list.size(); ++k) {
          const PlannedView pv = planned_view_from(list[k]);
          if (pv.index != first + static_cast<int>(k))
            return make_error(ErrorCode::kCorrupt, where + ": views must be numbered on from first_view");
          if (pv.index == static_cast<int>(s.manifest_.views.size())) s.manifest_.views.push_back(pv);
        }
      } catch (const json::exception& e) {
        return make_error(ErrorCode::kCorrupt, where + ": " + e.what());
      }
      s.adaptive_lines_.push_back(j);
      continue;
    }
    if (type == "adaptive_stopped") s.adaptive_lines_.push_back(j);
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
    } else if (type == "view_redo") {
      // The view is to be shot again: it is incomplete and its earlier frame lines no longer count.
      int view = -1;
      try {
        view = checked_int<int>(j.at("view"), "view");
      } catch (const json::exception& e) {
        return make_error(ErrorCode::kCorrupt, where + ": " + e.what());
      }
      s.complete_views_.erase(view);
      std::erase_if(s.frames_, [&](const FrameRecord& f) { return f.view == view; });
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
  VDRIG_TRY(s->repair_torn_journal());
  return s;
}

Status Session::lock() {
  if (lock_) return Status::ok();
  auto lock = lock_session(dir_);
  if (!lock) return lock.error();
  lock_ = std::make_shared<ProcessLock>(std::move(lock.value()));
  return repair_torn_journal();
}

namespace {

/// The journal, opened for appending (and reading its tail: O_RDWR) without following a link (session_files.hpp).
Result<detail::UniqueFd> open_journal_for_append(const fs::path& session_dir, const fs::path& journal_path) {
  auto dir = detail::open_session_dir(session_dir);
  if (!dir) return dir.error();
  const std::string name = journal_path.filename().string();
  const int fd = ::openat(dir->get(), name.c_str(), O_RDWR | O_APPEND | O_NOFOLLOW | O_CLOEXEC);
  if (fd >= 0) return detail::UniqueFd(fd);
  const int err = errno;
  VDRIG_TRY(detail::check_regular_or_absent_at(dir->get(), name, journal_path));
  return error_from_errno(err, "open " + journal_path.string());
}

/// Size of the journal up to and including its last newline: what remains once a torn last line is cut off.
Result<uint64_t> bytes_through_last_newline(int fd, uint64_t size, const fs::path& shown) {
  char buf[4096];
  uint64_t end = size;
  while (end > 0) {
    const uint64_t begin = end > sizeof buf ? end - sizeof buf : 0;
    const ssize_t n = ::pread(fd, buf, end - begin, static_cast<off_t>(begin));
    if (n != static_cast<ssize_t>(end - begin)) return error_from_errno(n < 0 ? errno : EIO, "read " + shown.string());
    for (ssize_t i = n; i > 0; --i)
      if (buf[i - 1] == '\n') return begin + static_cast<uint64_t>(i);
    end = begin;
  }
  return uint64_t{0};
}

/// Whether the journal (of `size` bytes) ends in a torn line: it is not empty and its last byte is not a newline.
Result<bool> ends_torn(int fd, uint64_t size, const fs::path& shown) {
  if (size == 0) return false;
  char last = 0;
  if (::pread(fd, &last, 1, static_cast<off_t>(size - 1)) != 1)
    return error_from_errno(errno ? errno : EIO, "read " + shown.string());
  return last != '\n';
}

}  // namespace

Status Session::repair_torn_journal(const ProcessLock* held_lock) {
  const fs::path path = layout().journal_file();
  if (!locked() && held_lock == nullptr)
    return make_error(ErrorCode::kInvalidArgument,
                      path.string() + ": only a writer holding the session's lock may repair the journal");
  auto journal = open_journal_for_append(dir_, path);
  if (!journal) return journal.error();
  struct stat st {};
  if (::fstat(journal->get(), &st) != 0) return error_from_errno(errno, "stat " + path.string());
  const uint64_t size = static_cast<uint64_t>(st.st_size);
  auto torn = ends_torn(journal->get(), size, path);
  if (!torn) return torn.error();
  if (torn.value()) {
    auto keep = bytes_through_last_newline(journal->get(), size, path);
    if (!keep) return keep.error();
    log::get("capture")->warn("session {}: cutting the torn last journal line off ({} bytes)", dir_.string(),
                              size - keep.value());
    if (::ftruncate(journal->get(), static_cast<off_t>(keep.value())) != 0 || ::fsync(journal->get()) != 0)
      return error_from_errno(errno, "cut the torn last line off " + path.string());
  }
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

/// Writes `bytes` as the new file `name` of the folder `frames_fd` (`path` names it in errors) and starts its
/// writeback without waiting for it, so the disk works while the next frame is being taken; durability comes later
/// (fsync_frame_file). A previous file of that name (an interrupted or redone view's) is removed first and the new
/// one created with O_EXCL | O_NOFOLLOW, so a link planted at the name is refused, never written through.
Status write_frame_file(int frames_fd, const std::string& name, const fs::path& path, const std::string& bytes) {
  VDRIG_TRY(detail::check_regular_or_absent_at(frames_fd, name, path));
  if (::unlinkat(frames_fd, name.c_str(), 0) != 0 && errno != ENOENT)
    return error_from_errno(errno, "remove the old " + path.string());
  const int fd = ::openat(frames_fd, name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    VDRIG_TRY(detail::check_regular_or_absent_at(frames_fd, name, path));  // a link planted meanwhile
    return error_from_errno(err, "create " + path.string());
  }
  if (const int err = write_all(fd, bytes.data(), bytes.size()); err != 0) {
    ::close(fd);
    return error_from_errno(err, "write " + path.string());
  }
  // Only a hint (an error here resurfaces at fsync): queue the pages for writeback now.
  (void)::sync_file_range(fd, 0, 0, SYNC_FILE_RANGE_WRITE);
  if (::close(fd) != 0) return error_from_errno(errno, "close " + path.string());
  return Status::ok();
}

/// fsync()s the file `name` of the folder `dir_fd` (opened without following a link).
Status fsync_at(int dir_fd, const std::string& name, const fs::path& path) {
  const int fd = ::openat(dir_fd, name.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return error_from_errno(errno, "open " + path.string());
  return fsync_and_close(fd, path);
}

}  // namespace

Status Session::append_journal(const std::string& text) {
  const fs::path path = layout().journal_file();
  if (write_hook_) VDRIG_TRY(write_hook_(path));
  auto journal = open_journal_for_append(dir_, path);
  if (!journal) return journal.error();
  const int fd = journal->get();
  struct stat st {};
  if (::fstat(fd, &st) != 0) return error_from_errno(errno, "stat " + path.string());
  // A line appended after a torn one would be glued onto it and corrupt the journal: the tail must be whole.
  auto torn = ends_torn(fd, static_cast<uint64_t>(st.st_size), path);
  if (!torn) return torn.error();
  if (torn.value()) {
    if (!locked())
      return make_error(ErrorCode::kInvalidArgument,
                        path.string() +
                            " ends in a torn line: not appended to (a capture holding the session lock, "
                            "or `vdrig session check --repair`, repairs it)");
    VDRIG_TRY(repair_torn_journal());
    if (::fstat(fd, &st) != 0) return error_from_errno(errno, "stat " + path.string());
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
  // Speed over size (encoding is the daemon's main per-frame CPU cost): zlib level 1 with the RLE strategy and the
  // SUB filter only; letting libpng try every filter on every row is about twice as slow for files ~15% smaller.
  auto encoded = encode_png(frame.image, PngCompression::kFastest);
  if (!encoded) return make_error(encoded.error().code, encoded.error().message + " (" + name + ")");
  const std::string& bytes = encoded.value();
  if (write_hook_) VDRIG_TRY(write_hook_(dir_ / name));
  // No temporary + rename: until the view's commit no journal line names this file, so a torn file is never read.
  auto frames_dir = detail::open_session_folder(dir_, layout().frames_dir().filename().string(), true);
  if (!frames_dir) return frames_dir.error();
  VDRIG_TRY(write_frame_file(frames_dir->get(), fs::path(name).filename().string(), dir_ / name, bytes));
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
    auto frames_dir = detail::open_session_folder(dir_, layout().frames_dir().filename().string(), false);
    if (!frames_dir) return frames_dir.error();
    for (const auto& r : batch)
      VDRIG_TRY(fsync_at(frames_dir->get(), fs::path(r.file).filename().string(), dir_ / r.file));
    if (::fsync(frames_dir->get()) != 0) return error_from_errno(errno, "fsync " + layout().frames_dir().string());
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

Status Session::append_planned_views(const std::vector<PlannedView>& views, const json& info) {
  if (!locked())
    return make_error(ErrorCode::kInvalidArgument, "session " + dir_.string() + ": planning views needs the lock");
  Manifest just_these;
  just_these.views = views;
  const int first = static_cast<int>(manifest_.views.size());
  for (size_t k = 0; k < views.size(); ++k)
    if (views[k].index != first + static_cast<int>(k))
      return make_error(ErrorCode::kInvalidArgument, "planned views must be numbered on from " + std::to_string(first));
  json line = info;
  line["type"] = "views_planned";
  line["first_view"] = first;
  line["views"] = just_these.to_json()["views"];
  line["utc"] = utc_now();
  // Round trip through the text, so that the views in memory are the ones a resumed process reads.
  const std::string text = line.dump() + "\n";
  const json back = json::parse(text);
  VDRIG_TRY(append_journal(text));
  for (const auto& v : back.at("views")) manifest_.views.push_back(planned_view_from(v));
  adaptive_lines_.push_back(back);
  return Status::ok();
}

Status Session::append_adaptive_stop(const std::string& reason, const json& info) {
  if (!locked())
    return make_error(ErrorCode::kInvalidArgument, "session " + dir_.string() + ": journaling a stop needs the lock");
  json line = info;
  line["type"] = "adaptive_stopped";
  line["reason"] = reason;
  line["utc"] = utc_now();
  VDRIG_TRY(append_journal(line.dump() + "\n"));
  adaptive_lines_.push_back(line);
  return Status::ok();
}

Result<cv::Mat> Session::load_image(const FrameRecord& record) const {
  VDRIG_TRY(check_no_symlinks_below(dir_, dir_ / record.file));
  return read_png(dir_ / record.file);
}

Status Session::mark_views_incomplete(const std::vector<int>& views, const std::string& reason) {
  if (!locked())
    return make_error(ErrorCode::kInvalidArgument,
                      "session " + dir_.string() + ": marking views incomplete needs the session's lock");
  for (const int v : views)
    if (v < 0 || v >= static_cast<int>(manifest_.views.size()))
      return make_error(ErrorCode::kInvalidArgument, "session " + dir_.string() + " has no view " + std::to_string(v) +
                                                         " (views 0.." + std::to_string(manifest_.views.size() - 1) +
                                                         ")");
  // The HDR files were merged from the frames being replaced: remove them first (a crash after this and before the
  // journal line leaves a complete view without its HDR, which `vdrig hdr` merges again).
  auto hdr_dir = detail::open_session_folder(dir_, layout().hdr_dir().filename().string(), false);
  if (hdr_dir) {
    for (const int v : views) {
      const fs::path hdr = layout().hdr_file(v);
      if (::unlinkat(hdr_dir->get(), hdr.filename().c_str(), 0) != 0 && errno != ENOENT)
        return error_from_errno(errno, "remove " + hdr.string());
    }
    if (::fsync(hdr_dir->get()) != 0) return error_from_errno(errno, "fsync " + layout().hdr_dir().string());
  } else if (hdr_dir.error().code != ErrorCode::kNotFound) {
    return hdr_dir.error();
  }
  std::string text;
  for (const int v : views)
    text += json{{"type", "view_redo"}, {"view", v}, {"reason", reason}, {"utc", utc_now()}}.dump() + "\n";
  VDRIG_TRY(append_journal(text));
  for (const int v : views) {
    complete_views_.erase(v);
    std::erase_if(frames_, [&](const FrameRecord& f) { return f.view == v; });
  }
  return Status::ok();
}

Status Session::update_extra(const json& extra) {
  manifest_.extra = extra;
  return write_file_atomic(layout().manifest_file(), manifest_.to_json().dump(2) + "\n");
}

}  // namespace vdrig::capture

#include "vdrig/capture/session_check.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <functional>
#include <optional>
#include <set>

#include "session_files.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;

std::string SessionProblem::describe() const {
  std::string line = path.string() + ": " + what;
  if (view >= 0) line += " (view " + std::to_string(view) + ")";
  if (repaired) line += ": repaired";
  return line;
}

int SessionCheckReport::unrepaired_count() const {
  int n = 0;
  for (const auto& p : problems) n += p.repaired ? 0 : 1;
  return n;
}

namespace {

/// A writer's temporary: ".NAME.tmpN" (core's temporary_sibling) or "NAME.tmp-XXXXXX" (mkstemp, the obsmap writer).
bool is_temporary_name(const std::string& name) {
  return (name.size() > 1 && name[0] == '.' && name.find(".tmp") != std::string::npos) ||
         name.find(".tmp-") != std::string::npos;
}

/// Removes the entry `relative` of the session (a link or a file: unlinkat never follows), from its parent folder
/// opened without following links.
Status remove_session_entry(const fs::path& dir, const fs::path& relative) {
  auto parent = detail::open_session_subfolder(dir, relative.parent_path());
  if (!parent) return parent.error();
  if (::unlinkat(parent->get(), relative.filename().c_str(), 0) != 0 && errno != ENOENT)
    return error_from_errno(errno, "remove " + (dir / relative).string());
  if (::fsync(parent->get()) != 0) return error_from_errno(errno, "fsync " + (dir / relative).parent_path().string());
  return Status::ok();
}

class Checker {
 public:
  Checker(const Session& session, const SessionCheckOptions& options) : session_(session), options_(options) {}

  void check_views() {
    const SessionLayout layout = session_.layout();
    for (const auto& planned : session_.manifest().views) {
      const int v = planned.index;
      if (!session_.view_complete(v)) continue;
      const auto frames = session_.frames_of_view(v);
      const int count = session_.view_frame_count(v);
      if (frames.empty()) {
        add(layout.journal_file(), "view " + std::to_string(v) + " is complete but the journal records no frame", v);
        continue;
      }
      if (count >= 0 && static_cast<int>(frames.size()) != count)
        add(layout.journal_file(),
            "view " + std::to_string(v) + " is complete with " + std::to_string(count) +
                " frames but the journal "
                "records " +
                std::to_string(frames.size()),
            v);
      for (const auto& rec : frames) {
        const fs::path expected = SessionLayout::frame_file_relative(rec.view, rec.bracket_index);
        if (fs::path(rec.file) != expected) {
          add(layout.journal_file(), "frame line names " + rec.file + " where the layout names " + expected.string(),
              v);
          continue;
        }
        auto image = session_.load_image(rec);
        if (!image) {
          add(session_.dir() / rec.file, image.error().message, v);
          continue;
        }
        const bool sixteen_bit = image->depth() == CV_16U;
        if (sixteen_bit != (rec.bits > 8))
          add(session_.dir() / rec.file,
              "decodes as " + std::string(sixteen_bit ? "16" : "8") + "-bit, the journal says " +
                  std::to_string(rec.bits) + " bits",
              v);
      }
    }
  }

  void check_journal() {
    const auto& warnings = session_.journal_warnings();
    for (size_t i = 0; i < warnings.size(); ++i) {
      // A torn last line (the last warning when there is one) is the one journal problem --repair deals with:
      // open_for_capture cut it off under the lock.
      const bool torn = session_.journal_torn() && i + 1 == warnings.size();
      add(session_.layout().journal_file(), warnings[i], -1, torn && options_.repair);
    }
  }

  /// Walks the session's folders without following links: links, foreign files and stale temporaries.
  void check_entries() {
    const SessionLayout layout = session_.layout();
    const auto name_of = [](const fs::path& p) { return p.filename().string(); };
    const std::set<std::string> top_files = {name_of(layout.manifest_file()), name_of(layout.journal_file()),
                                             name_of(layout.lock_file())};
    std::set<std::string> frame_names, hdr_names;
    for (const auto& v : session_.manifest().views) hdr_names.insert(name_of(layout.hdr_file(v.index)));
    walk(fs::path(), [&](const fs::path& rel, const fs::file_status& st) -> std::optional<std::string> {
      const std::string name = rel.filename().string();
      const fs::path parent = rel.parent_path();
      const bool is_dir = fs::is_directory(st);
      if (parent.empty()) {
        if (top_files.count(name)) return is_dir ? std::optional<std::string>("is not a regular file") : std::nullopt;
        for (const fs::path& folder : {layout.frames_dir(), layout.hdr_dir(), layout.calib_dir(), layout.obsmap_dir(),
                                       layout.maps_dir(), layout.renders_dir()})
          if (name == name_of(folder)) return is_dir ? std::nullopt : std::optional<std::string>("is not a folder");
        return "is not a file of a session";
      }
      const std::string folder = parent.begin()->string();
      if (folder == name_of(layout.renders_dir()) || folder == name_of(layout.calib_dir())) return std::nullopt;
      if (is_dir || std::distance(rel.begin(), rel.end()) != 2) return "is not a file of a session";
      if (folder == name_of(layout.frames_dir())) {
        // A frame file is exactly what SessionLayout names one (no std::regex: GCC 12 warns inside it under ASan).
        int view = -1, bracket_index = -1;
        const bool frame = std::sscanf(name.c_str(), "view_%d_e%d.png", &view, &bracket_index) == 2 && view >= 0 &&
                           bracket_index >= 0 &&
                           SessionLayout::frame_file_relative(view, bracket_index).filename().string() == name;
        return frame ? std::nullopt : std::optional<std::string>("is not a frame file");
      }
      if (folder == name_of(layout.hdr_dir()))
        return hdr_names.count(name) ? std::nullopt : std::optional<std::string>("is not the HDR file of a view");
      if (folder == name_of(layout.obsmap_dir()))
        return rel.extension() == ".vdobs" ? std::nullopt : std::optional<std::string>("is not an observation map");
      if (folder == name_of(layout.maps_dir()))
        return rel.extension() == ".exr" ? std::nullopt : std::optional<std::string>("is not a parameter map");
      return std::nullopt;
    });
  }

  void add(const fs::path& path, std::string what, int view = -1, bool repaired = false) {
    report.problems.push_back({path, std::move(what), view, repaired});
  }

  /// Removals --repair performs (links and stale temporaries), relative to the session folder, with their problem.
  std::vector<std::pair<fs::path, size_t>> removals;
  SessionCheckReport report;

 private:
  using Judge = std::function<std::optional<std::string>(const fs::path&, const fs::file_status&)>;

  void walk(const fs::path& relative_folder, const Judge& judge) {
    std::error_code ec;
    const fs::path folder = session_.dir() / relative_folder;
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
      const fs::path rel = relative_folder / it->path().filename();
      std::error_code st_ec;
      const fs::file_status st = it->symlink_status(st_ec);
      if (st_ec) {
        add(session_.dir() / rel, "cannot stat: " + st_ec.message());
        continue;
      }
      if (fs::is_symlink(st)) {
        removals.emplace_back(rel, report.problems.size());
        add(session_.dir() / rel, "is a symbolic link (vdrig never follows links in a session)");
        continue;
      }
      if (fs::is_regular_file(st) && is_temporary_name(rel.filename().string())) {
        check_temporary(rel);
        continue;
      }
      if (auto why = judge(rel, st)) {
        add(session_.dir() / rel, *why + ": foreign, left alone");
        continue;
      }
      if (fs::is_directory(st)) walk(rel, judge);
    }
    if (ec) add(folder, "cannot list: " + ec.message());
  }

  void check_temporary(const fs::path& rel) {
    std::error_code ec;
    const auto modified = fs::last_write_time(session_.dir() / rel, ec);
    if (ec) return;
    const auto age = fs::file_time_type::clock::now() - modified;
    if (age < options_.stale_temporary_age) {
      log::get("capture")->info("{}: a temporary written {} s ago: left (a writer may be at work)",
                                (session_.dir() / rel).string(),
                                std::chrono::duration_cast<std::chrono::seconds>(age).count());
      return;
    }
    removals.emplace_back(rel, report.problems.size());
    add(session_.dir() / rel, "stale temporary of a killed writer");
  }

  const Session& session_;
  const SessionCheckOptions& options_;
};

}  // namespace

Result<SessionCheckReport> check_session(const fs::path& dir, const SessionCheckOptions& options) {
  // Repairing writes: the lock first, then the journal is read (and a torn last line cut off) by open_for_capture.
  auto session = options.repair ? Session::open_for_capture(dir) : Session::open(dir);
  if (!session) return session.error();
  Checker checker(session.value(), options);
  checker.check_journal();
  checker.check_entries();
  checker.check_views();
  SessionCheckReport& report = checker.report;
  if (!options.repair) return report;

  for (const auto& [rel, problem] : checker.removals) {
    const Status removed = remove_session_entry(dir, rel);
    if (removed)
      report.problems[problem].repaired = true;
    else
      report.problems[problem].what += " (removing it failed: " + removed.error().message + ")";
  }
  std::set<int> bad_views;
  for (const auto& p : report.problems)
    if (p.view >= 0) bad_views.insert(p.view);
  if (!bad_views.empty()) {
    const std::vector<int> views(bad_views.begin(), bad_views.end());
    VDRIG_TRY(session->mark_views_incomplete(views, "vdrig session check --repair: a frame is bad"));
    report.views_marked_incomplete = views;
    for (auto& p : report.problems)
      if (p.view >= 0) p.repaired = true;
  }
  return report;
}

}  // namespace vdrig::capture

// check_session: fsck for a session folder (`vdrig session check S [--repair]`).
//
// What it checks: the manifest and the journal read (no symbolic link at either); the journal has no torn last line
// and names only planned views; every complete view has the frames its completion line counts, each named as
// SessionLayout names it, present, a regular file reached without a link, decoding at the bit depth its line
// records; nothing foreign in the session's folders (a symbolic link anywhere, a file the layout does not name),
// and no stale temporary (a killed writer's ".NAME.tmpN" or "NAME.tmp-XXXXXX" in the session, hdr/, obsmap/, maps/,
// calib/ or frames/).
//
// What --repair does, holding the session's lock (refused while a capture runs): cuts a torn last journal line off,
// removes symbolic links (the link, never what it points to) and stale temporaries, and marks every complete view
// with a bad frame incomplete through the journal (Session::mark_views_incomplete: one fsync'd append), so that
// `vdrig capture --resume` re-shoots it. Foreign regular files and ignored journal lines are reported, not touched.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::capture {

struct SessionProblem {
  std::filesystem::path path;  // the file or folder concerned
  std::string what;
  int view = -1;          // the complete view it spoils (re-shot after a repair); -1: none
  bool repaired = false;  // --repair dealt with it

  /// "<path>: <what>[ (view V)][: repaired]", the line `vdrig session check` prints.
  std::string describe() const;
};

struct SessionCheckOptions {
  bool repair = false;
  /// A temporary untouched for this long belongs to a killed writer; a younger one may be written right now (a fit
  /// does not hold the session lock) and is left alone.
  std::chrono::seconds stale_temporary_age{600};
};

struct SessionCheckReport {
  std::vector<SessionProblem> problems;
  std::vector<int> views_marked_incomplete;  // by --repair

  /// Problems --repair did not (or could not) deal with.
  int unrepaired_count() const;
};

/// Checks the session in `dir` (and repairs it with options.repair). A session that cannot be opened at all (no
/// manifest, a corrupt or linked manifest or journal) is the error of Session::open; so is a repair refused because
/// another process holds the session's lock.
Result<SessionCheckReport> check_session(const std::filesystem::path& dir, const SessionCheckOptions& options = {});

}  // namespace vdrig::capture

// Session report (`vdrig report`): one self-contained HTML page that shows a session at a glance. Everything is
// inline (images as data: URIs, plots as generated SVG, no script, no network fetch), so the file opens offline and
// can be mailed. docs/report.md describes the sections.
//
// Sections, each a <section id="..."> that is always present: "coverage" (the planned and captured directions on the
// hemisphere, coloured by capture order, with the planned route; held-out and excluded views marked), "views"
// (thumbnails of the merged views; per view: bracket exposures, saturated frames, clipped HDR fraction, capture time
// from journal.jsonl), "calibration" (intrinsics with the reprojection RMS, per-view marker reprojection error, the
// kinematic fit), "maps" (per fitted map: images of its parameters, false-colour fit residual, held-out error and
// lobe count with colour bars), "eval" (a simulated session's maps against the truth, as `vdrig eval`), "compare" (the
// `vdrig compare` table with thumbnails, from compare.json), "texels" (observations of the worst, the median and chosen
// texels on the hemisphere, coloured by the fit's residual) and "provenance" (software version, stage timings,
// commands). A part of the session that is not there yet (no calibration, no fit, no comparison) is named in its
// section with the command that makes it.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

struct ReportOptions {
  /// Texels plotted on the hemisphere besides the worst and the median of the first map: (s, t) pairs.
  std::vector<std::pair<int, int>> texels;
  /// The comparison to show; empty = SESSION/renders/compare/compare.json (compare_stage.hpp) when present.
  std::filesystem::path compare_json;
  int thumbnail_width_px = 200;  // compare thumbnails
  int map_image_px = 256;        // images of maps are shown this many pixels wide (pixelated; larger maps reduced)
  int view_thumbnail_px = 96;    // width of the views' thumbnails (0: none)
  int eval_directions = 1000;    // a simulated session's error against the truth: as vdrig eval's (0: not evaluated)
};

/// The report's HTML. Errors: a session that cannot be opened (no manifest, a damaged manifest or journal:
/// kNotFound/kCorrupt from capture::Session::open), an unreadable compare_json given explicitly. Parts of the session
/// that are missing or unreadable (a damaged map, a calibration file that does not parse) are reported in their
/// section, not as errors.
Result<std::string> build_report_html(const std::filesystem::path& session_dir, const ReportOptions& options = {});

/// build_report_html written atomically to `out`.
Status write_report(const std::filesystem::path& session_dir, const std::filesystem::path& out,
                    const ReportOptions& options = {});

}  // namespace vdrig::pipeline

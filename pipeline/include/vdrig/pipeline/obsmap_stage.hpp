// Observation-map stage: the session's HDR views sampled per texel of the surface (fitting/obsmap.hpp), in memory or
// streamed to a file (fitting/obsmap_file.hpp, docs/obsmap.md).
#pragma once

#include <filesystem>
#include <functional>
#include <vector>

#include "vdrig/capture/session.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::pipeline {

/// Builds the observation map of a session in memory (views listed in `views`, or all when empty; view i of the map
/// is views[i]). Needs S x T x views x 25 B: for small maps (tests, the demo). Large maps: build_session_obsmap_file.
Result<fitting::ObservationMap> build_session_obsmap(const capture::Session& session, int texels_s, int texels_t,
                                                     const std::vector<int>& views = {});

struct ObsMapBuildOptions {
  std::vector<int> views;  // session view indices; empty = every view of the manifest. View i of the file = views[i].
  fitting::ObsFileOptions file;
  std::function<void(int done, int total)> on_view;
};
/// Streams the session's HDR views into an observation-map file (fitting/obsmap_file.hpp, docs/obsmap.md): one HDR
/// image and one view's observations in memory at a time, so any resolution builds with bounded memory. Nothing is
/// at `path` unless it succeeds. Errors: an unreadable HDR view (kNotFound/kCorrupt: run `vdrig hdr` first), an HDR
/// view of another size than the camera (kCorrupt), a full disk (kNoSpace), invalid sizes (kInvalidArgument).
/// Pixels with a NaN or infinite channel (and their neighbours) are masked, never sampled, and counted in the log;
/// build_session_obsmap does the same.
Status build_session_obsmap_file(const capture::Session& session, int texels_s, int texels_t,
                                 const std::filesystem::path& path, const ObsMapBuildOptions& options = {});

/// SESSION/obsmap/<S>x<T>.vdobs over every view, built (build_session_obsmap_file) unless a file is there that is
/// still current: same size and view count, and newer than every HDR view and the geometric calibration (calib/),
/// so fitting several models at one resolution samples the views once. Returns the file's path.
Result<std::filesystem::path> session_obsmap_file(const capture::Session& session, int texels_s, int texels_t,
                                                  const ObsMapBuildOptions& options = {});

}  // namespace vdrig::pipeline

// What `vdrig view`, `vdrig render` and `vdrig inspect` read from a session besides the parameter map: the camera
// and view poses (pipeline::session_geometry), the views' HDR photographs, and a texel's observations.
#pragma once

#include <functional>
#include <string>

#include "vdrig/capture/session.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"

namespace vdrig::app {

struct SessionData {
  capture::Session session;
  pipeline::SessionGeometry geometry;

  int view_count() const { return static_cast<int>(geometry.poses.size()); }
  /// kInvalidArgument naming the range when `view` is not one of the session's views.
  Status check_view(int view) const;
  /// View `view`'s HDR image (SESSION/hdr/view_VVVV.exr): linear radiance, CV_32FC3 BGR.
  Result<cv::Mat> photo(int view) const;
  /// Every valid observation of texel (s, t) of a map of `map`'s size, held-out views included, from the session's
  /// observation-map file at that resolution (built first when missing or stale: pipeline::session_obsmap_file).
  Result<fitting::TexelObservations> observations(const fitting::ParameterMap& map, int s, int t) const;
};

Result<SessionData> open_session_data(const std::string& dir);

/// Parses "S,T" (two non-negative integers); kInvalidArgument otherwise.
Result<std::pair<int, int>> parse_texel(const std::string& text);

}  // namespace vdrig::app

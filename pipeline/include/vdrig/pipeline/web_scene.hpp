// The data of the web console's WebGL2 viewer (`vdrig serve`, docs/web.md): a session's parameter map with the
// surface shader's body (viewer::surface_glsl, the text `vdrig view` compiles, its model included), the session's
// camera and captured poses, and a captured view's HDR photograph. The page adds only its own main to the shader.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::pipeline {

struct WebScene {
  /// {"map", "maps", "model", "glsl", "texels": [S, T], "size_mm": [W, H], "layers", "camera": {"width", "height",
  /// "fx", "fy", "cx", "cy", "dist": [k1, k2, p1, p2, k3]}, "views": [{"index", "R": row-major 3x3, "centre": mm}]}
  nlohmann::json scene;
  std::vector<float> params;  ///< layers x T x S x 4, as SurfaceRenderer uploads them
};

/// The map `map_name` of SESSION/maps/ (its file MAP.exr; empty: the first in name order), for a calibrated session.
/// kNotFound naming what is missing (no maps, no such map, no calibration).
Result<WebScene> web_scene(const std::filesystem::path& session_dir, const std::string& map_name);

/// View `view`'s merged HDR photograph (SESSION/hdr/), BGR CV_32FC3 radiance.
Result<cv::Mat> web_photo(const std::filesystem::path& session_dir, int view);

/// The texel inspector's curve plot of texel (s, t) of map `map_name` (as web_scene) as SVG: viewer::curve_figure of
/// viewer::inspect_texel over the texel's observations in SESSION/obsmap/SxT.vdobs, held-out views marked, the plot
/// `vdrig view` draws on a click. kInvalidArgument for a texel outside the map, kNotFound for a missing map or
/// observation map (never built here: a GET writes nothing).
Result<std::string> web_texel_svg(const std::filesystem::path& session_dir, const std::string& map_name, int s, int t);

}  // namespace vdrig::pipeline

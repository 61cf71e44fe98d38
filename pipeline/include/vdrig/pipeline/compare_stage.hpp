// Compare stage (`vdrig compare`): fitted parameter maps rendered at captured views beside the HDR photographs of
// those views, with the difference summarised in the form of the source's Table 16.1: mean and standard deviation of
// |render - photo| in 8-bit codes, over the diffuse-dominated and the highlight pixels.
//
// Both images go through the same display tone mapping (viewer::tone_map: y = 1 - exp(-gamma x), sRGB, 8 bit): the
// render is the map's linear radiance from the view's pose (viewer::SurfaceRenderer, the viewer's shader), the photo
// is the view's merged HDR image (SESSION/hdr/view_VVVV.exr). A statistic is over pixel-channel samples: every
// colour channel of every counted pixel is one |render - photo| sample.
//
// Counted pixels: those whose ray meets the surface rectangle and whose HDR value is exact (HDR mask 0: some exposure
// saw them unclipped). They are split by the reference map's texel under the pixel, seen from the view:
//   - models with a diffuse part (ReflectanceModel::has_diffuse_part, e.g. Phong's Kd): the specular part is what the
//     texel's radiance toward v exceeds its diffuse part, against the total (RGB sums);
//   - any other model: the specular part is what the texel's radiance toward v exceeds its lowest radiance over
//     kFloorDirections directions of the upper hemisphere (its Lambertian floor), against the total.
// A pixel is "highlight" when specular > highlight_fraction x total, else "diffuse". The reference map is the first
// map of the comparison with a diffuse part, else the first map, so every map of one comparison is scored on the same
// pixels.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vdrig/capture/session.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::pipeline {

struct CompareOptions {
  double gamma = 1.0;               // display tone mapping, as `vdrig view --gamma`
  double highlight_fraction = 0.1;  // specular share of the total above which a pixel is "highlight"
  /// Where the images and compare.json go: OUT/<map file stem>/view_VVVV_{render,photo,diff_x8,regions}.png.
  /// Empty: session.layout().compare_dir().
  std::filesystem::path out_dir;
  std::string command;  // the command line that asked for the comparison, recorded in compare.json (may be empty)
};

/// Lambertian-floor directions for maps of models without a diffuse part (see the file comment).
inline constexpr int kFloorDirections = 100;

/// Mean and (population) standard deviation of |a - b| over pixel-channel samples, 8-bit codes.
struct DifferenceStats {
  long long samples = 0;  // pixels x channels; 0 when the region is empty (mean and stddev then 0)
  double mean = 0.0;
  double stddev = 0.0;
};

/// One map at one view.
struct ViewComparison {
  std::string map_name;  // the map file's stem, e.g. "phong:1"
  std::string model;     // its model spec
  int view = 0;
  DifferenceStats all, diffuse, highlight;
  /// Images (absolute paths): render and photo tone mapped, |difference| x 8 (clipped at 255), and the pixel regions
  /// (0 not counted, 128 diffuse, 255 highlight).
  std::filesystem::path render_png, photo_png, diff_png, regions_png;
};

struct CompareReport {
  double gamma = 1.0;
  double highlight_fraction = 0.1;
  std::string region_map;            // the map whose texels defined the regions
  std::string command;               // CompareOptions::command
  std::vector<ViewComparison> rows;  // map-major, views in the order asked
  std::filesystem::path json_file;   // where compare.json was written

  nlohmann::json to_json() const;
  static Result<CompareReport> from_json(const nlohmann::json& j);
  /// The Table 16.1 form: one row per map and view.
  std::string table() const;
};

/// The views `vdrig fit --holdout N` and `vdrig demo` hold out of a session of `views` views: N spread over the
/// session, never view 0 (the normal view): views * k / (N + 1) for k = 1..N.
std::vector<int> spread_holdout_views(int views, int count);

/// As above, but only among usable views: a view v with unusable[v] (excluded by the calibration, incomplete: its
/// observations are not in the fit anyway, so holding it out would test nothing) is replaced by the nearest usable
/// view not yet picked (v + 1, v - 1, v + 2, ...), never view 0. Fewer than `count` when too few views are usable.
/// `unusable` may be shorter than `views` (missing entries are usable).
std::vector<int> spread_holdout_views(int views, int count, const std::vector<bool>& unusable);

/// The views held out of a map's fit (its "vdrig.held_out_views" attribute, fitting/fit_map.hpp); kNotFound when the
/// map records none.
Result<std::vector<int>> held_out_views(const fitting::ParameterMap& map);

/// The views every one of `maps` held out of its fit (`vdrig compare --holdout`): kInvalidArgument naming the map when
/// one was fitted without --holdout (it saw every view: comparing it there would measure the fit, not a prediction)
/// or held out other views than the first map.
Result<std::vector<int>> common_held_out_views(const std::vector<std::filesystem::path>& maps);

/// The Table 16.1 statistics of |a - b| (CV_8UC3 each) over the non-zero pixels of `mask` (CV_8UC1).
DifferenceStats difference_stats(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);

/// The regions of one view (CV_8UC1: 0 not counted, 128 diffuse, 255 highlight) defined by `map` (see the file
/// comment); `hdr_mask` (CV_8UC1, 0 = exact radiance) excludes clipped pixels, empty = none clipped.
cv::Mat highlight_regions(const fitting::ParameterMap& map, const CameraModel& camera, const ViewPose& pose,
                          const cv::Mat& hdr_mask, double highlight_fraction);

/// Renders every map at every view and compares it with the photograph (OpenGL: needs a display, kUnsupported
/// without), writes the images and compare.json under options.out_dir. Errors: an unreadable map or HDR view
/// (kNotFound/kCorrupt, naming the file), a view outside the session or not merged, a map of another surface size
/// than the session's (kInvalidArgument).
Result<CompareReport> compare_maps(const capture::Session& session, const std::vector<std::filesystem::path>& maps,
                                   const std::vector<int>& views, const CompareOptions& options = {});

}  // namespace vdrig::pipeline

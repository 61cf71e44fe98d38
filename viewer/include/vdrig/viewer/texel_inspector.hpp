// Texel inspector: why a texel's fit looks the way it does. For one texel of a parameter map and its observations
// (the observation map the fit used), the data of two plots and a text block, and the plot image itself
// (`vdrig inspect`, and the overlay of `vdrig view` when a texel is clicked; docs/viewer.md):
//
//  - the curve: radiance along the great circle through the surface normal n and the texel's peak direction p
//    (ReflectanceModel::peak_direction: for a model with lobes, e.g. Phong, the strongest lobe's direction, i.e. the
//    mirror of the light; for other models the direction of the model's largest radiance on the hemisphere). A point of
//    the circle at signed angle a from the normal is
//        d(a) = cos(a) n + sin(a) u,  u = the unit horizontal vector toward p (x when p is the normal),
//    a in [-90, 90] degrees, positive on p's side. Observations within `band_deg` of the circle's plane are drawn
//    at their angle in that plane, a = atan2(d . u, d . n), over the model's curve;
//  - the hemisphere: every observation at the orthographic projection (d.x, d.y) of its direction, coloured by its
//    residual (model - observed, mean over RGB);
//  - the texel's parameters, fit RMS and held-out RMS (holdout.R/G/B channels, when the fit held views out).
//
// The curve is a plot::Figure (plot.hpp: one plotting path, SVG in the report, pixels here); the hemisphere and the
// text are drawn with OpenCV.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "vdrig/core/camera.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/viewer/plot.hpp"

namespace vdrig::viewer {

struct InspectOptions {
  int curve_points = 181;  // samples of the great circle, -90..90 degrees
  double band_deg = 10.0;  // observations this close to the circle's plane are drawn on the curve plot
};

/// One observation of the inspected texel.
struct InspectedObservation {
  Vec3d direction = Vec3d::UnitZ();  // unit, surface frame, toward the camera
  Vec3d observed = Vec3d::Zero();    // RGB radiance
  Vec3d model = Vec3d::Zero();       // the map's RGB radiance toward `direction`
  int view = -1;
  bool held_out = false;      // the view was held out of the fit
  double circle_deg = 0;      // angle in the great circle's plane, atan2(d . u, d . n)
  double off_circle_deg = 0;  // angle between d and that plane
  /// model - observed, averaged over RGB.
  double residual() const { return (model - observed).mean(); }
};

struct TexelInspection {
  int s = 0, t = 0;
  std::string model;                                       // the map's model name
  std::vector<std::pair<std::string, double>> parameters;  // channel name, value
  Vec3d fit_rms = Vec3d::Zero();                           // rms.R/G/B
  std::optional<Vec3d> holdout_rms;                        // holdout.R/G/B when the map has them
  int samples = 0;                                         // n
  // Phong maps with the support cap (channel m_capped): lobes of this texel whose shininess the sampling bounds, i.e.
  // where the map guesses the lobe's width (the surface may be glossier); nullopt for maps without the channel.
  std::optional<int> capped_lobes;
  Vec3d peak_direction = Vec3d::UnitZ();  // p
  Vec3d circle_u = Vec3d::UnitX();        // u
  double band_deg = 10.0;
  std::vector<double> curve_deg;                   // a, ascending
  std::vector<Vec3d> curve;                        // the map's RGB radiance toward d(a)
  std::vector<InspectedObservation> observations;  // every observation, in the order given
};

/// What the inspector says of a texel with `capped_lobes` > 0 lobes held at the sampling's shininess bound.
std::string capped_lobes_note(int capped_lobes);

/// The views held out of the map's fit, from its vdrig.held_out_views attribute ("3,7,11"; written by
/// fitting::fit_parameter_map); empty when absent.
std::vector<int> held_out_views(const fitting::ParameterMap& map);

/// The inspection of texel (s, t) (inside the map, checked) from its observations (all valid ones, held-out views
/// included: fitting::ObservationMap::texel or ObsTile::texel without a held-out list).
TexelInspection inspect_texel(const fitting::ParameterMap& map, int s, int t, const fitting::TexelObservations& obs,
                              const std::vector<int>& held_out = {}, const InspectOptions& options = {});

/// The curve plot: the model's R, G, B radiance along the great circle, the observations within band_deg of it
/// (circles; held-out views crosses), angle axis every 30 degrees, radiance axis with nice ticks. plot_inspection
/// draws it as pixels, `vdrig report` as SVG.
plot::Figure curve_figure(const TexelInspection& inspection);

/// The plot (CV_8UC3 BGR, width x height, at least 480 x 270): curve plot left, hemisphere right, text below.
cv::Mat plot_inspection(const TexelInspection& inspection, int width = 960, int height = 540);

/// The texel whose footprint the ray through `pixel` of `camera` at `pose` meets on the surface plane; nullopt when
/// the ray misses the surface (or points away from it).
std::optional<std::pair<int, int>> pick_texel(const CameraModel& camera, const ViewPose& pose,
                                              const fitting::ParameterMap& map, const Vec2d& pixel);

}  // namespace vdrig::viewer

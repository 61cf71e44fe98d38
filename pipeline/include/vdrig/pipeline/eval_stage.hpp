// Evaluation of a fitted parameter map against the simulator's ground truth, whatever the model: per texel, the
// relative RMS error of the map's radiance against the scene's true radiance over a dense set of directions on the
// upper hemisphere (and, given a session, over the directions that session sampled), summarised per material.
//
// Relative RMS of a texel over directions v_i and channels c: sqrt(sum (L_map - L_true)^2 / sum L_true^2) at the
// texel centre (a map whose Kd is 1.1 times a Lambertian truth scores exactly 0.1). Texels whose footprint touches
// more than one material (edges, marker rims) or lies outside the surface are in the error map but not in the
// per-material statistics. Where the truth is of Phong form (Scene::phong_truth) and the map's model has a diffuse
// part and lobes (ReflectanceModel::has_diffuse_part, ::lobes: Phong, or any model that describes itself so), the
// Phong parameters are compared too: Kd with the diffuse part, Ks and m with the strongest lobe's peak and exponent.
//
// The unknown scale: a response curve recovered from the images (Debevec-Malik, `vdrig calib response`) fixes each
// channel's radiance only up to a factor, so a map fitted on a session calibrated from its images is in other units
// than the simulator's truth (1.1x here), and every absolute figure carries that factor as an error no calibration
// from images can remove. The report therefore also gives the figures after one factor per channel (EvalReport::
// scale, map / truth: the median over the materials of each material's median texel ratio, a texel's ratio being its
// least-squares one over the dense directions) and that factor itself: a map right up to units scores as the truth, a
// wrong shape, colour of one material or lobe still shows.
#pragma once

#include <filesystem>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::pipeline {

/// What a simulated rig knows exactly and a real rig has to calibrate: the truth an evaluation compares with. Only
/// `vdrig eval` and tests that say by name they use the truth read it; every stage of the pipeline works from what
/// calibration wrote in SESSION/calib/ (geometry_stage.hpp, hdr_stage.hpp).
struct GroundTruth {
  CameraModel camera;           // intrinsics and distortion of the simulated camera
  rig::RigGeometry geometry;    // the stage's kinematics: measured pan/tilt -> surface pose
  ResponseCurve response;       // the simulated sensor's response curve
  calib::MarkerLayout markers;  // the scene's registration markers
  double surface_width_mm = 0.0, surface_height_mm = 0.0;

  /// The exact surface pose of a view taken at `measured` pan/tilt.
  ViewPose pose_at(const PanTilt& measured) const { return rig::surface_pose(geometry, measured); }
};

/// The ground truth of a rig config with a "sim" section, nullopt for any other (hardware) rig. An invalid "sim"
/// section or an unknown scene is the simulator's error.
Result<std::optional<GroundTruth>> ground_truth_of(const nlohmann::json& rig_config);

/// The simulated scene a session was captured from, as its rig config (manifest) names it; nullopt for a real rig's
/// session (no truth) and for a scene the simulator cannot make (a FILE.json gone). `vdrig report` asks it before it
/// evaluates a session's maps with evaluate_map, the one way the report reaches the truth.
std::optional<sim::Scene> simulated_scene_of(const nlohmann::json& rig_config);

struct EvalOptions {
  int dense_directions = 1000;  // Fibonacci points on the upper hemisphere (uniform in solid angle)
  /// A session whose views' directions are evaluated too (the view centres as the stage measured them, seen from
  /// each texel); empty = none.
  std::filesystem::path session_dir;
  /// Called as texel rows finish (from worker threads, one call at a time): texels done of the map's total.
  std::function<void(long texels_done, long texels_total)> on_progress;
};

/// Mean and 95th percentile of the texels' relative RMS.
struct RelativeRmsStats {
  double mean = 0.0;
  double p95 = 0.0;
  double p99 = 0.0;
  double max = 0.0;
};

/// Mean relative Phong parameter errors of a material's texels: |Kd_fit - Kd_true| / |Kd_true| (RGB norms, Kd_fit the
/// model's diffuse part), the same for Ks of the fit's strongest lobe (LobeSummary::peak_rgb), and |m_fit - m_true| /
/// m_true (LobeSummary::phong_exponent). ks_rel and shininess_rel are NaN when the
/// truth has no lobe (Lambertian).
struct PhongParameterErrors {
  double kd_rel = 0.0;
  double ks_rel = 0.0;
  double shininess_rel = 0.0;
};

struct MaterialEval {
  std::string name;
  int texels = 0;  // texels entirely on this material
  RelativeRmsStats dense;
  bool has_session = false;
  RelativeRmsStats session;  // when has_session
  bool has_phong = false;
  PhongParameterErrors phong;  // when has_phong
  /// The same figures with the map divided by EvalReport::scale (m does not depend on it).
  RelativeRmsStats dense_scaled;
  RelativeRmsStats session_scaled;    // when has_session
  PhongParameterErrors phong_scaled;  // when has_phong
};

struct EvalReport {
  std::string model;  // the map's model name
  int dense_directions = 0;
  int session_views = 0;                // 0 without a session
  std::vector<MaterialEval> materials;  // materials with at least one texel, in the scene's order
  /// Map radiance / true radiance per channel (R, G, B), the units a calibration from images cannot know (see
  /// the top of this file); 1 with the simulator's own response. NaN when no texel lies on a single material.
  Vec3d scale = Vec3d::Constant(std::numeric_limits<double>::quiet_NaN());
  /// What makes the figures doubtful, for the user: the map was fitted from (or evaluated over) a session captured
  /// from another scene than the one it is evaluated against (the errors then measure the scenes' difference).
  std::vector<std::string> warnings;
  /// One float channel per texel: "rel_rms" (dense), "rel_rms.scaled" (dense, after `scale`), "rel_rms.session" (with
  /// a session) and "material" (the scene
  /// material index at the texel centre; -1 outside the surface, -2 on a texel that touches several materials).
  ExrImage error_map;

  nlohmann::json to_json() const;
  /// A plain-text table, one row per material.
  std::string table() const;
};

/// n unit directions on the upper hemisphere (z > 0), a Fibonacci spiral: deterministic and uniform in solid angle.
std::vector<Vec3d> hemisphere_directions(int n);

/// The relative RMS of texel (s, t) of `map` against the scene's radiance at the texel centre over `directions`
/// (NaN when the truth is black there).
double texel_relative_rms(const fitting::ParameterMap& map, int s, int t, const sim::Scene& scene,
                          const std::vector<Vec3d>& directions);

/// Evaluates `map` against `scene` (kInvalidArgument when the map's surface size differs from the scene's; session
/// errors as capture::Session::open). The sessions the map names (its vdrig.source_session) and options.session_dir
/// are checked against `scene`: a simulated session of another scene is a warning in the report.
Result<EvalReport> evaluate_map(const fitting::ParameterMap& map, const sim::Scene& scene, const EvalOptions& options);

}  // namespace vdrig::pipeline

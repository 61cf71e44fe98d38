// Adaptive sampling (docs/sampling.md, "adaptive"): the rig captures a coarse base scheme, then batch by batch views
// that a planner chooses from what it has seen, until a view budget, a move-time budget, or until the planner's
// predicted held-out error stops improving.
//
// The loop lives here (capture links no solver); the planner that fits the coarse observation map is the
// pipeline's (pipeline/adaptive_stage.hpp) and reaches the loop through the ViewPlanner interface: an executable
// built with the pipeline registers it (register_view_planner_factory), a capture-only build refuses `adaptive:`
// with kUnsupported.
//
// Crash safety: each batch's views are appended to the journal (one "views_planned" line, fsync'd; Session replays
// it into manifest().views) before the rig moves, and the stop is journaled too ("adaptive_stopped"). A resumed
// capture first takes the views already planned and not yet complete, then plans the next batch from the same
// completed views as an uninterrupted run would: the same session, no view doubled (deterministic for a seed,
// given the same images).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/devices.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::capture {

/// `adaptive:N[,key=value]...` (docs/sampling.md has each key and why its default).
struct AdaptiveSettings {
  int max_views = 60;     // N: views in all, base included
  std::string base;       // the coarse scheme captured first (schemes.hpp grammar); empty: base_scheme()
  int batch = 6;          // views chosen per batch
  double max_move_s = 0;  // budget of planned stage move time, s (0: none)
  int res = 12;           // coarse observation map: res x res texels (unless given: default_res(model))
  // Candidates' zenith limit, and the base spiral's. 75, not 85 (until 2026-12-05): the observation map does not fit
  // a sample whose pixel footprint is over 4x the square-on one (fitting::kMaxFootprintStretch, 1 / cos 75.5 deg) on
  // a map finer than the camera resolves, so views past it are moves and brackets no fit of such a map uses.
  double max_zenith_deg = 75;
  double min_gain = 0.03;         // relative improvement of the predicted error that counts as progress
  int patience = 2;               // batches without progress before stopping
  double coverage_weight = 0.25;  // weight of coverage gaps against poorly constrained lobes
  double move_weight_s = 4.0;     // a move of this many seconds halves a candidate's value
  uint64_t seed = 1;              // jitter of the candidate directions
  std::string camera;             // intrinsics (camera.yml) the planner projects with; empty: SESSION/calib
  int ahead = 3;  // batches the plan looks ahead: routed at once, the next batch taken along that route (1: alone)
  std::string model = "phong";  // the planner's per-texel model: "phong" (lobes) or "ggx" (ggx:iso under the lamp)

  /// The coarse map's default side for a planner model: 12 for phong, 16 for ggx (docs/sampling.md has why).
  static int default_res(const std::string& model) { return model == "ggx" ? 16 : 12; }
  /// `base`, or when empty half of N in a spiral to max_zenith_deg (spiral:N/2:R@Z, R = sqrt(pi N / 16)):
  /// docs/sampling.md.
  std::string base_scheme() const;
  bool is_valid(std::string* why) const;
  std::string to_spec() const;
  nlohmann::json to_json() const;
};

/// Whether `spec` asks for adaptive sampling ("adaptive:" prefix).
bool is_adaptive_scheme(std::string_view spec);
/// Parses and validates `adaptive:N[,key=value]...`; kInvalidArgument naming the key and the rule it breaks.
Result<AdaptiveSettings> parse_adaptive_scheme(std::string_view spec);

/// What a planner is asked for one batch.
struct BatchRequest {
  const Session* session = nullptr;  // views complete so far: the data
  AdaptiveSettings settings;
  int batch = 0;              // 1, 2, ... (0 is the base scheme)
  int max_views = 0;          // at most this many: `ahead` batches (within the budget), of which the loop takes
                              // the next `settings.batch` along their route
  PanTilt from;               // where the stage is (the last view's target)
  rig::RigGeometry geometry;  // what planning aims with (geometry_from_rig_config)
  rig::StageSpec stage;
  std::vector<int> previous_batch;  // the views of the last batch (the base's: empty)
};

/// A planner's answer: directions in any order (the loop routes them), the predicted held-out error of the fit
/// on the views so far (a relative RMS), and what it saw, for the journal and the daemon.
struct BatchPlan {
  std::vector<Vec3d> directions;
  double predicted_error = 0;
  nlohmann::json info = nlohmann::json::object();
};

class ViewPlanner {
 public:
  virtual ~ViewPlanner() = default;
  virtual Result<BatchPlan> plan_batch(const BatchRequest& request) = 0;
  /// What the planner needs besides the views (e.g. the camera's intrinsics, the lamp), checked before a new session
  /// is made: a capture that could not plan its first batch is refused up front, not after its base views.
  /// `session_dir`: the session to be (its files do not exist yet); `rig_config`: the one it will be captured with.
  virtual Status check(const AdaptiveSettings& /*settings*/, const std::filesystem::path& /*session_dir*/,
                       const nlohmann::json& /*rig_config*/) const {
    return Status::ok();
  }
};

/// make_view_planner(), then its check() of `scheme` (an adaptive: spec) for a new session at `session_dir` captured
/// with `rig_config`.
Status check_adaptive_capture(const std::string& scheme, const std::filesystem::path& session_dir,
                              const nlohmann::json& rig_config);

using ViewPlannerFactory = std::function<std::unique_ptr<ViewPlanner>()>;
/// The planner of this executable (the pipeline's, when built): set once at start-up.
void register_view_planner_factory(ViewPlannerFactory factory);
/// kUnsupported when no planner was registered (a capture-only build).
Result<std::unique_ptr<ViewPlanner>> make_view_planner();

/// One batch as the journal records it.
struct AdaptiveBatch {
  int batch = 0;
  std::vector<int> views;
  double predicted_error = 0;
  double move_s = 0;
  nlohmann::json info;
};

/// The adaptive state of a session, replayed from its journal and manifest (extra.adaptive).
struct AdaptiveProgress {
  std::vector<AdaptiveBatch> batches;  // planned so far (views_planned lines), in order
  std::optional<std::string> stopped;  // why it stopped, once journaled
  double base_move_s = 0;
  double planned_move_s() const;
};
AdaptiveProgress adaptive_progress(const Session& session);

struct AdaptiveOptions {
  CaptureOptions capture;
  /// After each batch is journaled (before the rig moves) and when the loop stops.
  std::function<void(const AdaptiveProgress&)> on_batch;
};

/// Captures the session's views (base and planned batches), then plans, journals and captures batches until a
/// budget is reached or the predicted error stops improving; journals why it stopped. The session's manifest must
/// carry extra.adaptive (an adaptive session, plan_adaptive_manifest). Homes first and parks after (run_session).
Status run_adaptive_session(rig::Rig& rig, Session& session, ViewPlanner& planner, const AdaptiveOptions& options);

struct PlanRequest;
/// plan_manifest for `adaptive:...`: the base scheme's views, routed; the manifest's scheme is the adaptive spec and
/// extra.adaptive its settings. Errors: the settings' reasons, the base scheme's.
Result<Manifest> plan_adaptive_manifest(const PlanRequest& request);

}  // namespace vdrig::capture

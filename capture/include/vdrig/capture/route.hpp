// Route planning: in which order to visit a set of pan/tilt targets so that the stage spends the least time moving.
//
// Move model (rig::AxisSpec): each axis follows a trapezoidal speed profile (accelerate at accel_rad_s2 up to
// max_speed_rad_s, cruise, decelerate to a stop), or a triangular one when the distance is too short to reach max
// speed; both axes start together, so a move takes the longer of the two axis times. A continuous pan axis takes the
// shorter way round. The route is open: it starts at a given position and ends at the last target.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "vdrig/core/frame.hpp"
#include "vdrig/rig/devices.hpp"
#include "vdrig/rig/motion.hpp"

namespace vdrig::capture {

// The move model lives with the rig (rig/motion.hpp); capture uses it unchanged.
using rig::axis_move_time_s;
using rig::move_time_s;

/// Total move time (s) from `start` through targets[order[0]], targets[order[1]], ...
double route_time_s(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> targets,
                    std::span<const std::size_t> order);

struct RouteOptions {
  /// Wall-clock budget for the improvement passes; planning stops with the best order so far when it runs out.
  /// The nearest-neighbour start and the final comparison with the naive order are always done.
  double time_budget_s = 0.5;
  /// At most this many improvement passes (a pass tries every 2-opt and Or-opt move once).
  int max_passes = 1000;
};

struct Route {
  std::vector<std::size_t> order;  // a permutation of 0..n-1: visit targets[order[k]] k-th
  double planned_time_s = 0.0;     // route_time_s of `order`
  double naive_time_s = 0.0;       // route_time_s of the given order 0..n-1
  bool used_naive_order = false;   // the planner could not beat the given order, which is returned as is
  int passes = 0;                  // improvement passes run
  bool budget_exhausted = false;   // stopped by the time budget or max_passes rather than a local optimum
  double planning_s = 0.0;         // wall-clock time spent planning
};

/// Plans a visit order: nearest neighbour from `start`, then 2-opt (segment reversal) and Or-opt (moving runs of
/// 1..3 targets, either way round) until no move helps or the budget is spent. Never slower than the given order:
/// when the improved nearest-neighbour route is not faster, the given order itself is improved, and if that
/// does not help either, the given order is returned (planned_time_s <= naive_time_s always).
Route plan_route(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> targets,
                 const RouteOptions& options = {});

/// Cheapest insertion of `target` into the open route start -> route[0] -> route[1] -> ...: the move time it adds
/// (s) and where it goes (before route[position]; route.size(): at the end). Adaptive sampling weighs a candidate
/// view by this against the route it is planning (capture/adaptive.hpp).
struct Insertion {
  double added_s = 0.0;
  std::size_t position = 0;
};
Insertion cheapest_insertion(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> route,
                             const PanTilt& target);

}  // namespace vdrig::capture

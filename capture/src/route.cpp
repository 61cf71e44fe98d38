#include "vdrig/capture/route.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::capture {
namespace {

using Clock = std::chrono::steady_clock;

/// Strictly better by more than rounding noise: keeps the improvement loops from cycling on ties.
constexpr double kImprovement = 1e-9;

/// Move times between the start (node 0) and the targets (nodes 1..n). Precomputed up to a few thousand nodes
/// (8 bytes per pair), computed on demand above that.
class CostTable {
 public:
  CostTable(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> targets)
      : spec_(spec), n_(targets.size() + 1) {
    nodes_.reserve(n_);
    nodes_.push_back(start);
    nodes_.insert(nodes_.end(), targets.begin(), targets.end());
    if (n_ <= kMaxTable) {
      table_.resize(n_ * n_);
      for (std::size_t i = 0; i < n_; ++i) {
        table_[i * n_ + i] = 0.0;
        for (std::size_t j = i + 1; j < n_; ++j)
          table_[i * n_ + j] = table_[j * n_ + i] = move_time_s(spec_, nodes_[i], nodes_[j]);
      }
    }
  }
  double operator()(std::size_t a, std::size_t b) const {
    return table_.empty() ? move_time_s(spec_, nodes_[a], nodes_[b]) : table_[a * n_ + b];
  }

 private:
  static constexpr std::size_t kMaxTable = 4000;
  rig::StageSpec spec_;
  std::size_t n_;
  std::vector<PanTilt> nodes_;
  std::vector<double> table_;
};

/// Path of target nodes (1..n) after the fixed start node 0; the route is open at its end.
using Path = std::vector<std::size_t>;

double path_cost(const CostTable& c, const Path& p) {
  double t = 0.0;
  std::size_t prev = 0;
  for (std::size_t node : p) {
    t += c(prev, node);
    prev = node;
  }
  return t;
}

Path nearest_neighbour(const CostTable& c, std::size_t n) {
  Path p;
  p.reserve(n);
  std::vector<bool> used(n + 1, false);
  std::size_t cur = 0;
  for (std::size_t k = 0; k < n; ++k) {
    std::size_t best = 0;
    double best_t = std::numeric_limits<double>::infinity();
    for (std::size_t j = 1; j <= n; ++j) {
      if (used[j]) continue;
      const double t = c(cur, j);
      if (t < best_t) best_t = t, best = j;
    }
    used[best] = true;
    p.push_back(best);
    cur = best;
  }
  return p;
}

/// One sweep of 2-opt over an open path with a fixed start: reversing p[i..j] replaces the edges (a, b) and
/// (c, d) by (a, c) and (b, d); move times are symmetric, so the reversed inside costs the same.
bool two_opt_pass(const CostTable& c, Path& p, Clock::time_point deadline, bool& out_of_time) {
  const std::size_t n = p.size();
  bool improved = false;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    if (Clock::now() > deadline) {
      out_of_time = true;
      return improved;
    }
    const std::size_t a = i == 0 ? 0 : p[i - 1];
    for (std::size_t j = i + 1; j < n; ++j) {
      const std::size_t b = p[i], cc = p[j];
      const bool has_d = j + 1 < n;
      const std::size_t d = has_d ? p[j + 1] : 0;
      const double before = c(a, b) + (has_d ? c(cc, d) : 0.0);
      const double after = c(a, cc) + (has_d ? c(b, d) : 0.0);
      if (after < before - kImprovement) {
        std::reverse(p.begin() + static_cast<std::ptrdiff_t>(i), p.begin() + static_cast<std::ptrdiff_t>(j) + 1);
        improved = true;
      }
    }
  }
  return improved;
}

/// One sweep of Or-opt: moves each run p[i..i+k-1] (k = 1..3) to the best other place, forward or reversed.
bool or_opt_pass(const CostTable& c, Path& p, Clock::time_point deadline, bool& out_of_time) {
  const std::size_t n = p.size();
  bool improved = false;
  for (std::size_t k = 1; k <= 3 && k < n; ++k) {
    for (std::size_t i = 0; i + k <= n; ++i) {
      if (Clock::now() > deadline) {
        out_of_time = true;
        return improved;
      }
      const std::size_t a = i == 0 ? 0 : p[i - 1];
      const std::size_t b = p[i], e = p[i + k - 1];
      const bool has_f = i + k < n;
      const std::size_t f = has_f ? p[i + k] : 0;
      const double removal_gain = c(a, b) + (has_f ? c(e, f) - c(a, f) : 0.0);
      // Candidate places: after x, where x is the start (m = -1) or p[m] outside the run, and y its successor
      // once the run is taken out. Skipping m = i - 1 (the run's own place).
      double best_delta = -kImprovement;
      std::ptrdiff_t best_m = -2;
      bool best_reversed = false;
      for (std::ptrdiff_t m = -1; m < static_cast<std::ptrdiff_t>(n); ++m) {
        if (m >= static_cast<std::ptrdiff_t>(i) - 1 && m < static_cast<std::ptrdiff_t>(i + k)) continue;
        const std::size_t x = m < 0 ? 0 : p[m];
        std::ptrdiff_t ny = m + 1;
        if (ny == static_cast<std::ptrdiff_t>(i)) ny += static_cast<std::ptrdiff_t>(k);
        const bool has_y = ny < static_cast<std::ptrdiff_t>(n);
        const std::size_t y = has_y ? p[ny] : 0;
        const double base = has_y ? c(x, y) : 0.0;
        const double fwd = c(x, b) + (has_y ? c(e, y) : 0.0) - base - removal_gain;
        const double rev = c(x, e) + (has_y ? c(b, y) : 0.0) - base - removal_gain;
        if (fwd < best_delta) best_delta = fwd, best_m = m, best_reversed = false;
        if (rev < best_delta) best_delta = rev, best_m = m, best_reversed = true;
      }
      if (best_m == -2) continue;
      Path run(p.begin() + static_cast<std::ptrdiff_t>(i), p.begin() + static_cast<std::ptrdiff_t>(i + k));
      if (best_reversed) std::reverse(run.begin(), run.end());
      Path rest;
      rest.reserve(n);
      for (std::size_t q = 0; q < n; ++q)
        if (q < i || q >= i + k) rest.push_back(p[q]);
      // Position in `rest` right after p[best_m] (or at the front for the start).
      std::size_t insert_at = 0;
      if (best_m >= 0) insert_at = static_cast<std::size_t>(best_m) < i ? best_m + 1 : best_m + 1 - k;
      rest.insert(rest.begin() + static_cast<std::ptrdiff_t>(insert_at), run.begin(), run.end());
      p = std::move(rest);
      improved = true;
    }
  }
  return improved;
}

/// Improves `p` in place until a local optimum of both neighbourhoods, the deadline or `max_passes`.
void improve(const CostTable& c, Path& p, Clock::time_point deadline, int max_passes, int& passes, bool& exhausted) {
  for (;;) {
    if (passes >= max_passes) {
      exhausted = true;
      return;
    }
    ++passes;
    bool out_of_time = false;
    const bool a = two_opt_pass(c, p, deadline, out_of_time);
    const bool b = !out_of_time && or_opt_pass(c, p, deadline, out_of_time);
    if (out_of_time) {
      exhausted = true;
      return;
    }
    if (!a && !b) return;
  }
}

}  // namespace

double route_time_s(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> targets,
                    std::span<const std::size_t> order) {
  double t = 0.0;
  PanTilt cur = start;
  for (std::size_t k : order) {
    VDRIG_CHECK(k < targets.size(), "route_time_s: order index out of range");
    t += move_time_s(spec, cur, targets[k]);
    cur = targets[k];
  }
  return t;
}

Route plan_route(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> targets,
                 const RouteOptions& options) {
  const auto t0 = Clock::now();
  const auto deadline = t0 + std::chrono::duration_cast<Clock::duration>(
                                 std::chrono::duration<double>(std::max(0.0, options.time_budget_s)));
  const std::size_t n = targets.size();
  Route route;
  route.order.resize(n);
  std::iota(route.order.begin(), route.order.end(), std::size_t{0});
  route.naive_time_s = route_time_s(spec, start, targets, route.order);
  route.planned_time_s = route.naive_time_s;
  route.used_naive_order = true;
  if (n < 2) return route;

  const CostTable cost(spec, start, targets);
  Path naive(n);
  std::iota(naive.begin(), naive.end(), std::size_t{1});
  const double naive_cost = path_cost(cost, naive);

  Path best = nearest_neighbour(cost, n);
  improve(cost, best, deadline, options.max_passes, route.passes, route.budget_exhausted);
  if (path_cost(cost, best) >= naive_cost) {
    // The given order was already good (e.g. a sweep planned by hand): polish it instead.
    best = naive;
    improve(cost, best, deadline, options.max_passes, route.passes, route.budget_exhausted);
  }
  std::vector<std::size_t> order(n);
  for (std::size_t k = 0; k < n; ++k) order[k] = best[k] - 1;
  const double planned = route_time_s(spec, start, targets, order);
  if (planned < route.naive_time_s) {
    route.order = std::move(order);
    route.planned_time_s = planned;
    route.used_naive_order = false;
  }
  route.planning_s = std::chrono::duration<double>(Clock::now() - t0).count();
  log::get("capture")->debug(
      "route over {} targets: {:.1f} s planned vs {:.1f} s in the given order ({} passes, {:.3f} s)", n,
      route.planned_time_s, route.naive_time_s, route.passes, route.planning_s);
  return route;
}

Insertion cheapest_insertion(const rig::StageSpec& spec, const PanTilt& start, std::span<const PanTilt> route,
                             const PanTilt& target) {
  Insertion best{std::numeric_limits<double>::infinity(), route.size()};
  const PanTilt* prev = &start;
  for (std::size_t k = 0; k <= route.size(); ++k) {
    const double to = move_time_s(spec, *prev, target);
    // At the end the route is open: nothing to rejoin.
    const double added =
        k < route.size() ? to + move_time_s(spec, target, route[k]) - move_time_s(spec, *prev, route[k]) : to;
    if (added < best.added_s - kImprovement) best = {added, k};
    if (k < route.size()) prev = &route[k];
  }
  return best;
}

}  // namespace vdrig::capture

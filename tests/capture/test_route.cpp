// Route planning: trapezoidal move times against hand-computed values, and visit orders that are never slower than
// the given one, near-optimal on small cases (brute force) and clearly faster on shuffled schemes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numeric>
#include <random>

#include "vdrig/capture/route.hpp"
#include "vdrig/capture/schemes.hpp"

namespace vdrig::capture {
namespace {

rig::AxisSpec axis(double v, double a, bool continuous = false) {
  rig::AxisSpec s;
  s.min_rad = deg_to_rad(-360.0);
  s.max_rad = deg_to_rad(360.0);
  s.max_speed_rad_s = v;
  s.accel_rad_s2 = a;
  s.continuous = continuous;
  return s;
}

rig::StageSpec stage(bool continuous_pan = false) {
  rig::StageSpec s;
  s.pan = axis(deg_to_rad(30.0), deg_to_rad(60.0), continuous_pan);
  s.tilt = axis(deg_to_rad(20.0), deg_to_rad(40.0));
  s.tilt.min_rad = deg_to_rad(-5.0);
  s.tilt.max_rad = deg_to_rad(90.0);
  return s;
}

bool is_permutation_of_n(const std::vector<std::size_t>& order, std::size_t n) {
  std::vector<std::size_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 0; i < sorted.size(); ++i)
    if (sorted[i] != i) return false;
  return sorted.size() == n;
}

void check_route(const Route& r, const rig::StageSpec& spec, const PanTilt& start, const std::vector<PanTilt>& t,
                 const std::string& what) {
  ASSERT_TRUE(is_permutation_of_n(r.order, t.size())) << what;
  std::vector<std::size_t> naive(t.size());
  std::iota(naive.begin(), naive.end(), std::size_t{0});
  EXPECT_DOUBLE_EQ(r.naive_time_s, route_time_s(spec, start, t, naive)) << what;
  EXPECT_DOUBLE_EQ(r.planned_time_s, route_time_s(spec, start, t, r.order)) << what;
  EXPECT_LE(r.planned_time_s, r.naive_time_s) << what;
  std::cout << what << ": " << t.size() << " targets, naive " << r.naive_time_s << " s, planned " << r.planned_time_s
            << " s (" << 100.0 * r.planned_time_s / std::max(1e-12, r.naive_time_s) << "%), " << r.passes << " passes, "
            << r.planning_s * 1e3 << " ms" << (r.budget_exhausted ? ", budget exhausted" : "")
            << (r.used_naive_order ? ", given order kept" : "") << "\n";
}

// --- move times ---

TEST(MoveTime, TrapezoidAndTriangleAgainstHandValues) {
  const rig::AxisSpec a = axis(0.5, 1.0);  // full speed after 0.5 s and 0.125 rad; trapezoid from 0.25 rad on
  EXPECT_DOUBLE_EQ(axis_move_time_s(0.0, a), 0.0);
  EXPECT_DOUBLE_EQ(axis_move_time_s(1.0, a), 2.5);   // 1 / 0.5 + 0.5 / 1
  EXPECT_DOUBLE_EQ(axis_move_time_s(-1.0, a), 2.5);  // direction does not matter
  EXPECT_DOUBLE_EQ(axis_move_time_s(0.16, a), 0.8);  // triangle: 2 sqrt(0.16 / 1)
  EXPECT_DOUBLE_EQ(axis_move_time_s(0.25, a), 1.0);  // the two formulas meet at v^2 / a
  EXPECT_NEAR(axis_move_time_s(0.25 - 1e-12, a), 1.0, 1e-9);
  const rig::AxisSpec b = axis(deg_to_rad(30.0), deg_to_rad(60.0));
  EXPECT_NEAR(axis_move_time_s(deg_to_rad(90.0), b), 3.5, 1e-12);  // 90 / 30 + 30 / 60
  EXPECT_NEAR(axis_move_time_s(deg_to_rad(5.0), b), 2.0 * std::sqrt(5.0 / 60.0), 1e-12);
}

TEST(MoveTime, BothAxesAtOnceAndTheShortWayRound) {
  rig::StageSpec s;
  s.pan = axis(0.5, 1.0);
  s.tilt = axis(0.25, 0.5);
  // pan 1 rad: 2.5 s; tilt 0.16 rad: 0.16 >= 0.125 so 0.16 / 0.25 + 0.25 / 0.5 = 1.14 s -> 2.5 s.
  EXPECT_DOUBLE_EQ(move_time_s(s, {0.0, 0.0}, {1.0, 0.16}), 2.5);
  // tilt 1 rad: 4 + 0.5 = 4.5 s dominates pan 0.16 rad (0.8 s).
  EXPECT_DOUBLE_EQ(move_time_s(s, {0.2, 0.1}, {0.36, 1.1}), 4.5);
  // 170 deg -> -170 deg: 340 deg the long way on a limited axis, 20 deg the short way on a continuous one.
  const PanTilt from{deg_to_rad(170.0), 0.0}, to{deg_to_rad(-170.0), 0.0};
  EXPECT_NEAR(move_time_s(s, from, to), deg_to_rad(340.0) / 0.5 + 0.5, 1e-12);
  s.pan.continuous = true;
  EXPECT_NEAR(move_time_s(s, from, to), deg_to_rad(20.0) / 0.5 + 0.5, 1e-12);
  EXPECT_NEAR(move_time_s(s, to, from), deg_to_rad(20.0) / 0.5 + 0.5, 1e-12);
  // Several whole turns apart is no move at all on a continuous axis.
  EXPECT_NEAR(move_time_s(s, {0.3, 0.0}, {0.3 + 4.0 * kPi, 0.0}), 0.0, 1e-6);
}

// --- routes ---

TEST(Route, EmptyAndSingleTarget) {
  const auto spec = stage();
  const Route r0 = plan_route(spec, {}, {});
  EXPECT_TRUE(r0.order.empty());
  EXPECT_EQ(r0.planned_time_s, 0.0);
  const std::vector<PanTilt> one = {{1.0, 0.5}};
  const Route r1 = plan_route(spec, {}, one);
  ASSERT_EQ(r1.order.size(), 1u);
  EXPECT_DOUBLE_EQ(r1.planned_time_s, move_time_s(spec, {}, one[0]));
}

TEST(Route, NearOptimalOnSmallCasesByBruteForce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pan(-kPi, kPi), tilt(0.0, kPi / 2.0);
  const auto spec = stage();
  double worst_ratio = 1.0;
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<PanTilt> t(8);
    for (auto& p : t) p = {pan(rng), tilt(rng)};
    std::vector<std::size_t> perm(t.size());
    std::iota(perm.begin(), perm.end(), std::size_t{0});
    double optimum = 1e300;
    do {
      optimum = std::min(optimum, route_time_s(spec, {}, t, perm));
    } while (std::next_permutation(perm.begin(), perm.end()));
    const Route r = plan_route(spec, {}, t);
    ASSERT_TRUE(is_permutation_of_n(r.order, t.size()));
    EXPECT_GE(r.planned_time_s, optimum - 1e-9);
    EXPECT_LE(r.planned_time_s, r.naive_time_s);
    worst_ratio = std::max(worst_ratio, r.planned_time_s / optimum);
  }
  std::cout << "8 random targets x 20: worst planned / optimum = " << worst_ratio << "\n";
  EXPECT_LT(worst_ratio, 1.08);
}

TEST(Route, NeverSlowerThanNaiveOnRandomInputs) {
  std::mt19937 rng(11);
  for (bool continuous : {false, true}) {
    const auto spec = stage(continuous);
    for (std::size_t n : {2u, 3u, 5u, 17u, 60u, 250u}) {
      for (int trial = 0; trial < 3; ++trial) {
        std::uniform_real_distribution<double> pan(spec.pan.min_rad, spec.pan.max_rad), tilt(0.0, kPi / 2.0);
        std::vector<PanTilt> t(n);
        for (auto& p : t) p = {pan(rng), tilt(rng)};
        const PanTilt start{pan(rng), tilt(rng)};
        const Route r = plan_route(spec, start, t);
        check_route(r, spec, start, t, std::string("random") + (continuous ? " (continuous pan)" : ""));
      }
    }
  }
}

TEST(Route, NeverSlowerThanAGoodGivenOrder) {
  // Targets already in the best order (a monotone sweep from the start): the planner cannot beat it and must
  // return it, or something exactly as fast.
  const auto spec = stage();
  std::vector<PanTilt> t;
  for (int k = 1; k <= 40; ++k) t.push_back({deg_to_rad(7.0 * k), deg_to_rad(30.0)});
  const Route r = plan_route(spec, {0.0, deg_to_rad(30.0)}, t);
  check_route(r, spec, {0.0, deg_to_rad(30.0)}, t, "monotone sweep");
  EXPECT_NEAR(r.planned_time_s, r.naive_time_s, 1e-9);
}

std::vector<PanTilt> scheme_targets(const std::string& spec_text, const rig::StageSpec& spec) {
  auto dirs = generate(spec_text);
  EXPECT_TRUE(dirs.is_ok());
  const TargetPlan plan = plan_targets(rig::RigGeometry{}, spec, dirs->directions);
  EXPECT_TRUE(plan.unreachable.empty()) << spec_text;
  std::vector<PanTilt> t;
  for (const auto& v : plan.reachable) t.push_back(v.pan_tilt);
  return t;
}

TEST(Route, SchemesInGivenOrderAreNeverSlower) {
  for (bool continuous : {false, true}) {
    const auto spec = stage(continuous);
    for (const char* s : {"icosahedron:2", "latlong:8:80", "spiral:300:11@80", "stratified:12x12:4@80",
                          "icosahedron:2+dense-around:225,46.7:15:40"}) {
      const auto t = scheme_targets(s, spec);
      const Route r = plan_route(spec, {}, t);
      check_route(r, spec, {}, t, std::string(s) + (continuous ? " (continuous pan)" : ""));
    }
  }
}

TEST(Route, ClearlyFasterOnAShuffledIcosahedron) {
  const auto spec = stage();
  auto t = scheme_targets("icosahedron:2", spec);
  ASSERT_EQ(t.size(), 73u);
  std::mt19937 rng(2024);
  std::shuffle(t.begin(), t.end(), rng);
  const Route r = plan_route(spec, {}, t);
  check_route(r, spec, {}, t, "shuffled icosahedron:2");
  // A random tour of 73 directions crosses the hemisphere each time (~6 s a move); a planned one steps between
  // neighbours (~1 s): expect well under half.
  EXPECT_LT(r.planned_time_s, 0.4 * r.naive_time_s);
  EXPECT_FALSE(r.used_naive_order);
}

TEST(Route, LargeInputStaysWithinItsBudget) {
  const auto spec = stage();
  auto t = scheme_targets("icosahedron:4", spec);  // 1249 directions
  std::mt19937 rng(3);
  std::shuffle(t.begin(), t.end(), rng);
  RouteOptions options;
  options.time_budget_s = 0.3;
  const Route r = plan_route(spec, {}, t, options);
  check_route(r, spec, {}, t, "shuffled icosahedron:4");
  EXPECT_LT(r.planned_time_s, 0.3 * r.naive_time_s);
  // The budget bounds the improvement passes; the nearest-neighbour start and the move-time table come on top
  // (well under a second even under sanitizers).
  EXPECT_LT(r.planning_s, options.time_budget_s + 3.0);
}

// Adaptive sampling weighs a candidate by the move time its insertion into the route adds (capture/adaptive.hpp):
// the cheapest position, against every position tried by recomputing the whole route.
TEST(Route, CheapestInsertionIsTheBestPositionByRecomputation) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pan(-kPi, kPi), tilt(0.0, kPi / 2.0);
  const auto spec = stage();
  const PanTilt start{0.3, 0.2};
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<PanTilt> route(static_cast<size_t>(trial % 7));
    for (auto& p : route) p = {pan(rng), tilt(rng)};
    const PanTilt target{pan(rng), tilt(rng)};
    auto total = [&](const std::vector<PanTilt>& r) {
      std::vector<std::size_t> order(r.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      return route_time_s(spec, start, r, order);
    };
    const double before = total(route);
    double best = 1e300;
    std::size_t best_at = 0;
    for (std::size_t k = 0; k <= route.size(); ++k) {
      auto r = route;
      r.insert(r.begin() + static_cast<std::ptrdiff_t>(k), target);
      if (total(r) - before < best - 1e-9) {
        best = total(r) - before;
        best_at = k;
      }
    }
    const Insertion got = cheapest_insertion(spec, start, route, target);
    EXPECT_NEAR(got.added_s, best, 1e-9) << "trial " << trial;
    EXPECT_EQ(got.position, best_at) << "trial " << trial;
  }
}

}  // namespace
}  // namespace vdrig::capture

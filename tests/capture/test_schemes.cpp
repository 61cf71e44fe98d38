// Sampling schemes: counts against the source thesis and closed forms, coverage, spec parsing, and the inverse
// kinematics round trip that turns directions into pan/tilt targets.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <set>

#include "vdrig/capture/schemes.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::capture {
namespace {

double zenith_deg(const Vec3d& d) { return rad_to_deg(std::acos(std::clamp(d.z(), -1.0, 1.0))); }

SampleSet must_generate(const std::string& spec) {
  auto s = generate(spec);
  EXPECT_TRUE(s.is_ok()) << spec << ": " << (s ? "" : s.error().describe());
  return s ? *s : SampleSet{};
}

void expect_unit_and_within(const std::vector<Vec3d>& dirs, double max_zenith_deg, const std::string& what) {
  for (const Vec3d& d : dirs) {
    ASSERT_NEAR(d.norm(), 1.0, 1e-12) << what;
    ASSERT_LE(zenith_deg(d), max_zenith_deg + 1e-7) << what;
    ASSERT_GE(d.z(), -1e-12) << what;
  }
}

/// Largest angle (deg) from any point of the hemisphere cap (probed on a fine grid) to its nearest sample: the
/// biggest hole in the coverage.
double covering_radius_deg(const std::vector<Vec3d>& dirs, double cap_deg) {
  double worst = 0.0;
  for (int i = 0; i <= 60; ++i) {
    const double zen = deg_to_rad(cap_deg) * i / 60.0;
    const int na = std::max(1, static_cast<int>(std::lround(240 * std::sin(zen))));
    for (int j = 0; j < na; ++j) {
      const Vec3d p = direction_from_spherical(2.0 * kPi * j / na, zen);
      double best = kPi;
      for (const Vec3d& d : dirs) best = std::min(best, angle_between(p, d));
      worst = std::max(worst, best);
    }
  }
  return rad_to_deg(worst);
}

/// Smallest and largest nearest-neighbour angle (deg) over the samples.
std::pair<double, double> nearest_neighbour_range_deg(const std::vector<Vec3d>& dirs) {
  double lo = 180.0, hi = 0.0;
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    double nn = kPi;
    for (std::size_t j = 0; j < dirs.size(); ++j)
      if (i != j) nn = std::min(nn, angle_between(dirs[i], dirs[j]));
    lo = std::min(lo, rad_to_deg(nn));
    hi = std::max(hi, rad_to_deg(nn));
  }
  return {lo, hi};
}

// --- icosahedron ---

TEST(Icosahedron, CountsMatchTheSourceThesis) {
  // The thesis's 17-, 73- and 305-direction hemispheres are levels 1, 2, 3 with the horizon excluded; its
  // 289-direction one is level 3 without the 16 points just above the horizon (zenith 85.3 deg).
  EXPECT_EQ(icosahedron_directions(1).size(), 17u);
  EXPECT_EQ(icosahedron_directions(2).size(), 73u);
  EXPECT_EQ(icosahedron_directions(3).size(), 305u);
  EXPECT_EQ(must_generate("icosahedron:3@85").directions.size(), 289u);
  EXPECT_EQ(must_generate("icosahedron:3@85").above_limit_removed, 16u);
  for (int level = 0; level <= 5; ++level)
    EXPECT_EQ(icosahedron_directions(level).size(), icosahedron_hemisphere_count(level)) << "level " << level;
  EXPECT_EQ(icosahedron_hemisphere_count(0), 4u);
  EXPECT_EQ(icosahedron_hemisphere_count(4), 1249u);
}

TEST(Icosahedron, UniformUnitAndAboveTheHorizon) {
  for (int level = 1; level <= 3; ++level) {
    const auto dirs = icosahedron_directions(level);
    expect_unit_and_within(dirs, 90.0, "icosahedron");
    for (const Vec3d& d : dirs) EXPECT_GT(d.z(), 1e-9);
    // Geodesic subdivision keeps neighbours within a factor ~1.2 of each other (the 12 original vertices have 5
    // neighbours, the rest 6): min/max nearest-neighbour ratio well above 0.7.
    const auto [lo, hi] = nearest_neighbour_range_deg(dirs);
    EXPECT_GT(lo / hi, 0.7) << "level " << level << ": " << lo << " .. " << hi;
  }
  // Level >= 1 contains the normal itself.
  const auto l2 = icosahedron_directions(2);
  EXPECT_TRUE(std::any_of(l2.begin(), l2.end(), [](const Vec3d& d) { return (d - Vec3d::UnitZ()).norm() < 1e-12; }));
}

// --- latlong ---

TEST(LatLong, BandCountsFollowSineOfZenith) {
  // latlong:6:90: bands every 15 deg; ring k holds round(2 pi sin(15 k deg) / (15 deg)) = round(24 sin(15 k deg)):
  // 6.21 -> 6, 12 -> 12, 16.97 -> 17, 20.78 -> 21, 23.18 -> 23, 24 -> 24; plus the normal: 104.
  const std::vector<int> expected = {6, 12, 17, 21, 23, 24};
  for (int k = 1; k <= 6; ++k) EXPECT_EQ(latlong_band_count(k, 6, deg_to_rad(90.0)), expected[k - 1]) << k;
  const auto dirs = must_generate("latlong:6:90").directions;
  ASSERT_EQ(dirs.size(), 104u);
  EXPECT_NEAR((dirs[0] - Vec3d::UnitZ()).norm(), 0.0, 1e-15);
  // Every direction lies on one of the declared rings, and each ring has its count.
  std::map<long, int> per_ring;
  for (std::size_t i = 1; i < dirs.size(); ++i) {
    const double z = zenith_deg(dirs[i]);
    const long ring = std::lround(z / 15.0);
    EXPECT_NEAR(z, 15.0 * ring, 1e-9);
    ++per_ring[ring];
  }
  for (int k = 1; k <= 6; ++k) EXPECT_EQ(per_ring[k], expected[k - 1]) << "ring " << k;
  expect_unit_and_within(dirs, 90.0, "latlong");
}

TEST(LatLong, DefaultZenithMaxAndGlobalLimit) {
  // Default outermost band 80 deg; with @60 and no explicit maximum the bands span 0..60.
  const auto def = must_generate("latlong:4").directions;
  double zmax = 0;
  for (const auto& d : def) zmax = std::max(zmax, zenith_deg(d));
  EXPECT_NEAR(zmax, 80.0, 1e-9);
  const auto lim = must_generate("latlong:4@60").directions;
  zmax = 0;
  for (const auto& d : lim) zmax = std::max(zmax, zenith_deg(d));
  EXPECT_NEAR(zmax, 60.0, 1e-9);
  // An explicit maximum beyond the limit: the outer band is cut off and counted.
  const auto cut = must_generate("latlong:6:90@80");
  EXPECT_EQ(cut.above_limit_removed, 24u);
  EXPECT_EQ(cut.directions.size(), 80u);
}

// --- stratified ---

TEST(Stratified, ExactlyOnePointPerEqualAreaCell) {
  for (double cap_deg : {90.0, 75.0}) {
    const int nz = 12, na = 16;
    const auto dirs = stratified_directions(nz, na, 42, deg_to_rad(cap_deg));
    ASSERT_EQ(dirs.size(), static_cast<std::size_t>(nz * na));
    const double one_minus_cos_cap = 1.0 - std::cos(deg_to_rad(cap_deg));
    std::set<std::pair<int, int>> cells;
    for (std::size_t k = 0; k < dirs.size(); ++k) {
      const SphericalDir s = spherical_from_direction(dirs[k]);
      const double u = (1.0 - std::cos(s.zenith_rad)) / one_minus_cos_cap;
      const double v = s.azimuth_rad / (2.0 * kPi);
      const int row = static_cast<int>(std::floor(u * nz)), col = static_cast<int>(std::floor(v * na));
      // Generated row-major: point k belongs to cell (k / na, k % na) and lies inside it.
      EXPECT_EQ(row, static_cast<int>(k) / na) << k;
      EXPECT_EQ(col, static_cast<int>(k) % na) << k;
      cells.insert({row, col});
    }
    EXPECT_EQ(cells.size(), static_cast<std::size_t>(nz * na));
    expect_unit_and_within(dirs, cap_deg, "stratified");
  }
}

TEST(Stratified, DeterministicPerSeedAndDifferentAcrossSeeds) {
  const auto a = must_generate("stratified:8x8:7").directions;
  const auto b = must_generate("stratified:8x8:7").directions;
  const auto c = must_generate("stratified:8x8:8").directions;
  ASSERT_EQ(a.size(), 64u);
  ASSERT_EQ(c.size(), 64u);
  int differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i], b[i]);
    differ += (a[i] - c[i]).norm() > 1e-6;
  }
  EXPECT_GT(differ, 60);
  // Equal-area cells: a 16x16 grid covers the hemisphere with no hole much bigger than a cell (cell ~ 9 deg).
  EXPECT_LT(covering_radius_deg(must_generate("stratified:16x16:3").directions, 90.0), 14.0);
}

// --- spiral ---

TEST(Spiral, OnTheHemisphereAndRoughlyUniform) {
  // 300 points with R = sqrt(pi N / 8) ~ 11 turns: spacing along the curve ~ spacing between turns.
  const auto dirs = must_generate("spiral:300:11").directions;
  ASSERT_EQ(dirs.size(), 300u);
  expect_unit_and_within(dirs, 90.0, "spiral");
  // An ideal uniform set of 300 points on 2 pi sr spaces neighbours ~ sqrt(2 pi / 300 * 2 / sqrt 3) = 8.9 deg;
  // icosahedron:3 (305 points) measures 7.9..9.1 deg and a 9.0 deg covering radius; this spiral 6.9..8.4 and 9.0.
  const auto [lo, hi] = nearest_neighbour_range_deg(dirs);
  EXPECT_GT(lo, 6.0);
  EXPECT_LT(hi, 9.5);
  EXPECT_LT(covering_radius_deg(dirs, 90.0), 9.5);
  // Too few turns for the count leaves holes between the turns (spiral:300:5: covering radius 17 deg).
  EXPECT_GT(covering_radius_deg(must_generate("spiral:300:5").directions, 90.0), 15.0);
  // Same count and bounds with a cap.
  const auto capped = must_generate("spiral:200:9@70").directions;
  ASSERT_EQ(capped.size(), 200u);
  expect_unit_and_within(capped, 70.0, "spiral@70");
  EXPECT_LT(covering_radius_deg(capped, 70.0), 10.0);
}

// --- dense-around and composition ---

TEST(DenseAround, FillsTheConeAndComposesWithoutDuplicates) {
  const auto cone =
      dense_around_directions(direction_from_spherical(deg_to_rad(225.0), deg_to_rad(46.7)), deg_to_rad(15.0), 40);
  ASSERT_EQ(cone.size(), 40u);
  const Vec3d centre = direction_from_spherical(deg_to_rad(225.0), deg_to_rad(46.7));
  double far = 0.0;
  for (const auto& d : cone) {
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    far = std::max(far, rad_to_deg(angle_between(d, centre)));
  }
  EXPECT_LE(far, 15.0 + 1e-9);
  EXPECT_GT(far, 13.0);  // it fills the cone rather than bunching at the centre
  const auto both = must_generate("icosahedron:2+dense-around:225,46.7:15:40");
  EXPECT_EQ(both.directions.size(), 73u + 40u);
  EXPECT_EQ(both.duplicates_removed, 0u);
  // Composing a scheme with itself removes every second copy.
  const auto twice = must_generate("icosahedron:2+icosahedron:2+latlong:3:60+latlong:3:60");
  const std::size_t ll = latlong_directions(3, deg_to_rad(60)).size();
  // Unique: the 73 icosahedron directions and the latlong ones but its normal, which is the icosahedron's pole.
  EXPECT_EQ(twice.directions.size(), 73u + ll - 1u);
  EXPECT_EQ(twice.duplicates_removed, 73u + ll + 1u);
  for (std::size_t i = 0; i < twice.directions.size(); ++i)
    for (std::size_t j = i + 1; j < twice.directions.size(); ++j)
      ASSERT_GT((twice.directions[i] - twice.directions[j]).norm(), 1e-9);
}

TEST(DenseAround, ConeCrossingTheLimitIsCutAndCounted) {
  const auto s = must_generate("dense-around:0,80:20:50@85");
  EXPECT_GT(s.above_limit_removed, 0u);
  EXPECT_EQ(s.directions.size() + s.above_limit_removed, 50u);
  expect_unit_and_within(s.directions, 85.0, "dense-around@85");
}

// --- parsing ---

TEST(Parse, RejectsBadSpecsWithTheReason) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"", "empty"},
      {"cube:3", "unknown scheme"},
      {"icosahedron:9", "L must be 0..6"},
      {"icosahedron:x", "integer"},
      {"icosahedron:2:3", "expected icosahedron:L"},
      {"spiral:100", "spiral:N:R"},
      {"spiral:0:3", "N must be"},
      {"spiral:100:-1", "R (turns)"},
      {"latlong:0", "BANDS"},
      {"latlong:4:120", "ZENITH_MAX_DEG"},
      {"stratified:8", "NZxNA"},
      {"stratified:8x0", ">= 1"},
      {"stratified:8x8:-1", "SEED"},
      {"dense-around:225:15:40", "AZ_DEG,ZEN_DEG"},
      {"dense-around:225,45:15", "expected dense-around"},
      {"dense-around:225,95:15:40", "ZEN_DEG"},
      {"dense-around:400,45:15:40", "AZ_DEG"},
      {"dense-around:225,45:0:40", "CONE_DEG"},
      {"icosahedron:2+", "empty component"},
      {"icosahedron:2@95", "(0, 90]"},
      {"icosahedron:2@abc", "number of degrees"},
      {"spiral:nan:3", "integer"},
      {"latlong:4:inf", "number"},
  };
  for (const auto& [spec, reason] : bad) {
    auto r = parse_scheme(spec);
    ASSERT_FALSE(r.is_ok()) << "accepted: " << spec;
    EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(r.error().message.find(reason), std::string::npos)
        << spec << " -> " << r.error().message << " (wanted \"" << reason << "\")";
  }
}

TEST(Parse, RoundTripsThroughCanonicalText) {
  for (const std::string spec : {"icosahedron:2+dense-around:225,46.7:15:40", "spiral:300:11@80",
                                 "latlong:6:85+stratified:4x8:9", " icosahedron:3 @ 85 "}) {
    auto a = parse_scheme(spec);
    ASSERT_TRUE(a.is_ok()) << spec << ": " << a.error().describe();
    auto b = parse_scheme(to_spec(*a));
    ASSERT_TRUE(b.is_ok()) << to_spec(*a);
    EXPECT_EQ(to_spec(*a), to_spec(*b));
    const auto da = generate(*a).directions, db = generate(*b).directions;
    ASSERT_EQ(da.size(), db.size()) << spec;
    for (std::size_t i = 0; i < da.size(); ++i) EXPECT_LT((da[i] - db[i]).norm(), 1e-12);
  }
}

// --- inverse kinematics round trip and targets ---

rig::StageSpec wide_stage() {
  rig::StageSpec s;
  s.pan = {deg_to_rad(-360.0), deg_to_rad(360.0), deg_to_rad(30.0), deg_to_rad(60.0), false};
  s.tilt = {deg_to_rad(-5.0), deg_to_rad(90.0), deg_to_rad(30.0), deg_to_rad(60.0), false};
  return s;
}

void expect_round_trip(const rig::RigGeometry& g, const rig::StageSpec& spec, const std::vector<Vec3d>& dirs,
                       const std::string& what) {
  double worst_deg = 0.0;
  std::size_t missed = 0;
  for (const Vec3d& d : dirs) {
    const auto pt = rig::inverse_kinematics(g, spec, d, 0.3);
    if (!pt) {
      ++missed;
      continue;
    }
    EXPECT_GE(pt->tilt_rad, spec.tilt.min_rad);  // strictly: stages refuse targets past a limit
    EXPECT_LE(pt->tilt_rad, spec.tilt.max_rad);
    EXPECT_GE(pt->pan_rad, spec.pan.min_rad);
    EXPECT_LE(pt->pan_rad, spec.pan.max_rad);
    worst_deg = std::max(worst_deg, rad_to_deg(angle_between(rig::view_direction(g, *pt), d)));
  }
  EXPECT_EQ(missed, 0u) << what;
  EXPECT_LT(worst_deg, 0.01) << what;
  std::cout << what << ": worst round-trip error " << worst_deg << " deg over " << dirs.size() << " directions\n";
}

std::vector<Vec3d> round_trip_directions(double zenith_max_deg) {
  // A fine latlong plus the pole neighbourhood, where azimuth is ill-conditioned.
  std::vector<Vec3d> dirs = latlong_directions(45, deg_to_rad(zenith_max_deg));
  for (double zen_deg : {1e-7, 1e-4, 0.01, 0.5, 2.0})
    for (int a = 0; a < 8; ++a) dirs.push_back(direction_from_spherical(a * kPi / 4.0, deg_to_rad(zen_deg)));
  return dirs;
}

TEST(InverseKinematics, RoundTripIdealRig) {
  rig::RigGeometry g;
  expect_round_trip(g, wide_stage(), round_trip_directions(89.9), "ideal rig");
}

TEST(InverseKinematics, RoundTripWithSurfaceOffset) {
  // Up to 85 deg: an offset below the surface (z < 0) pushes the tilt of grazing directions past the 90 deg limit.
  const auto dirs = round_trip_directions(85.0);
  for (const Vec3d& offset : {Vec3d(12.0, -7.0, 3.0), Vec3d(0.0, 0.0, 40.0), Vec3d(150.0, 80.0, -25.0)}) {
    rig::RigGeometry g;
    g.camera_distance_mm = 1200.0;
    g.surface_offset_mm = offset;
    expect_round_trip(g, wide_stage(), dirs,
                      "offset (" + std::to_string(offset.x()) + ", " + std::to_string(offset.y()) + ", " +
                          std::to_string(offset.z()) + ")");
  }
}

TEST(InverseKinematics, NormalKeepsThePreferredPan) {
  rig::RigGeometry g;
  const auto pt = rig::inverse_kinematics(g, wide_stage(), Vec3d::UnitZ(), 0.7);
  ASSERT_TRUE(pt.has_value());
  EXPECT_DOUBLE_EQ(pt->pan_rad, 0.7);
  EXPECT_NEAR(pt->tilt_rad, 0.0, 1e-12);
}

TEST(InverseKinematics, PanIsTheTurnNearestThePreferredOne) {
  // On a +-360 deg stage every pan has two or three whole-turn equivalents: the one nearest the preferred pan wins.
  rig::RigGeometry g;
  g.surface_offset_mm = Vec3d(5.0, 3.0, 1.0);
  for (double preferred : {0.0, 2.0 * kPi, -5.0}) {
    for (const Vec3d& d : icosahedron_directions(2)) {
      const auto pt = rig::inverse_kinematics(g, wide_stage(), d, preferred);
      ASSERT_TRUE(pt.has_value());
      for (double other : {pt->pan_rad - 2.0 * kPi, pt->pan_rad + 2.0 * kPi}) {
        const bool in_limits = other >= wide_stage().pan.min_rad && other <= wide_stage().pan.max_rad;
        EXPECT_TRUE(!in_limits || std::abs(other - preferred) >= std::abs(pt->pan_rad - preferred) - 1e-12)
            << "preferred " << preferred << ": got " << pt->pan_rad << " but " << other << " is nearer";
      }
      if (preferred == 0.0) {
        EXPECT_LE(std::abs(pt->pan_rad), kPi + 1e-12);
      }
    }
  }
}

TEST(Targets, UnreachableDirectionsAreListedNotDropped) {
  // Tilt limited to 0..60 deg and pan to [-90, 90] deg (not continuous): the negative-tilt branch is closed, so
  // only azimuths with pi/2 - azimuth in [-90, 90] deg (i.e. azimuth in [0, 180] deg) are reachable.
  rig::StageSpec spec = wide_stage();
  spec.tilt.min_rad = 0.0;
  spec.tilt.max_rad = deg_to_rad(60.0);
  spec.pan.min_rad = deg_to_rad(-90.0);
  spec.pan.max_rad = deg_to_rad(90.0);
  const auto dirs = must_generate("icosahedron:3").directions;
  for (const Vec3d& offset : {Vec3d::Zero().eval(), Vec3d(10.0, 5.0, 0.0)}) {
    rig::RigGeometry g;
    g.surface_offset_mm = offset;
    const TargetPlan plan = plan_targets(g, spec, dirs);
    ASSERT_EQ(plan.reachable.size() + plan.unreachable.size(), dirs.size());
    std::vector<bool> seen(dirs.size(), false);
    std::size_t expected_unreachable = 0;
    for (const Vec3d& d : dirs) {
      const SphericalDir s = spherical_from_direction(d);
      const bool clearly_out = s.zenith_rad > deg_to_rad(60.5) || (s.zenith_rad > 0.05 && s.azimuth_rad > kPi + 0.05);
      expected_unreachable += clearly_out;
    }
    EXPECT_GE(plan.unreachable.size(), expected_unreachable);
    EXPECT_GT(plan.reachable.size(), dirs.size() / 4);
    for (const auto& t : plan.reachable) {
      seen[t.index] = true;
      EXPECT_EQ(t.direction, dirs[t.index]);
      EXPECT_LT(rad_to_deg(angle_between(rig::view_direction(g, t.pan_tilt), t.direction)), 0.01);
      EXPECT_GE(t.pan_tilt.pan_rad, spec.pan.min_rad);
      EXPECT_LE(t.pan_tilt.pan_rad, spec.pan.max_rad);
      EXPECT_GE(t.pan_tilt.tilt_rad, spec.tilt.min_rad);
      EXPECT_LE(t.pan_tilt.tilt_rad, spec.tilt.max_rad);
    }
    for (const auto& u : plan.unreachable) {
      EXPECT_FALSE(seen[u.index]);
      seen[u.index] = true;
      EXPECT_EQ(u.direction, dirs[u.index]);
      EXPECT_FALSE(rig::inverse_kinematics(g, spec, u.direction).has_value());
    }
    EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](bool b) { return b; }));
  }
}

}  // namespace
}  // namespace vdrig::capture

// Hemisphere sampling schemes: which view directions to photograph a surface from, and the pan/tilt targets that
// realise them on a given rig.
//
// Directions are unit vectors in the surface frame (z = the surface normal); spherical angles are `azimuth` (from +x
// toward +y) and `zenith` (from +z), as fixed in docs/conventions.md. Degrees appear only in the spec text.
//
// Spec grammar (no spaces; see docs/sampling.md for the counts and the reasoning):
//   spec       := component ('+' component)* ['@' MAX_ZENITH_DEG]
//   component  := 'spiral:' N ':' R                      N points on a spherical spiral of R turns
//               | 'icosahedron:' L                       upper half of a geodesic icosphere subdivided L times
//               | 'latlong:' BANDS [':' ZENITH_MAX_DEG]  zenith bands, azimuth count ~ sin(zenith), plus the normal
//               | 'stratified:' NZ 'x' NA [':' SEED]     one jittered point per cell of an equal-area NZ x NA grid
//               | 'dense-around:' AZ_DEG ',' ZEN_DEG ':' CONE_DEG ':' N   N points filling a cone around a direction
// The global limit '@MAX_ZENITH_DEG' (default 90) bounds the cap that spiral and stratified cover (so their counts
// stay N and NZ*NA) and then removes every point of every component whose zenith exceeds it (icosahedron, latlong,
// dense-around). Components are concatenated in order; directions within 1e-9 of an earlier one are removed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "vdrig/core/frame.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/devices.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::capture {

enum class SchemeKind { kSpiral, kIcosahedron, kLatLong, kStratified, kDenseAround };

/// One component of a scheme; only the fields of its kind are meaningful.
struct SchemeComponent {
  SchemeKind kind = SchemeKind::kIcosahedron;
  int count = 0;                   // spiral: N points; dense-around: N points
  double turns = 0.0;              // spiral: R turns around the normal
  int level = 0;                   // icosahedron: subdivision level L (0..6)
  int bands = 0;                   // latlong: number of zenith bands
  double band_zenith_max_rad = 0;  // latlong: zenith of the outermost band; 0 = default (min(80 deg, global limit))
  int zenith_cells = 0;            // stratified: NZ cells along cos(zenith)
  int azimuth_cells = 0;           // stratified: NA cells along azimuth
  uint64_t seed = 1;               // stratified: jitter seed (same seed, same points, on every platform)
  double centre_azimuth_rad = 0;   // dense-around: cone axis
  double centre_zenith_rad = 0;
  double cone_rad = 0;  // dense-around: cone half-angle
};

/// A parsed, validated scheme. `max_zenith_rad` is the global zenith limit (pi/2 when not given).
struct SamplingScheme {
  std::vector<SchemeComponent> components;
  double max_zenith_rad = kPi / 2.0;

  /// Checks every field against the limits documented in docs/sampling.md; `why` gets the first violation.
  bool is_valid(std::string* why = nullptr) const;
};

/// Parses and validates a spec (grammar above). kInvalidArgument with the offending component and the reason.
/// The scheme `vdrig capture`, vdrigd's "start" and `vdrig demo` use when none is given (docs/conventions.md, "One
/// meaning per flag"): one default everywhere.
inline constexpr const char* kDefaultScheme = "latlong:8";

Result<SamplingScheme> parse_scheme(std::string_view spec);

/// Canonical spec text of a scheme (parse_scheme(to_spec(s)) gives back s up to float printing).
std::string to_spec(const SamplingScheme& scheme);

/// The directions of a scheme and what composing it removed.
struct SampleSet {
  std::vector<Vec3d> directions;        // unit, z >= 0, zenith <= the global limit, no two within 1e-9
  std::size_t duplicates_removed = 0;   // directions equal (within 1e-9) to an earlier one
  std::size_t above_limit_removed = 0;  // directions beyond the global zenith limit
};

/// Generates the directions of a valid scheme (VDRIG_CHECKs validity), in component order.
SampleSet generate(const SamplingScheme& scheme);

/// parse_scheme + generate.
Result<SampleSet> generate(std::string_view spec);

// --- The individual generators (no limit filtering, no de-duplication). ---

/// N points along a spherical spiral from the normal (zenith 0) to `cap_zenith_rad`, making `turns` turns around
/// the normal: zenith grows linearly with the turn angle and the points are equally spaced in arc length along the
/// curve, at (i + 0.5) / N of its length. Roughly uniform when turns ~ sqrt(pi N / 8) for a full hemisphere.
std::vector<Vec3d> spiral_directions(int count, double turns, double cap_zenith_rad);

/// Vertices of a geodesic icosphere subdivided `level` times (each edge halved and projected onto the sphere),
/// oriented with an edge midpoint on the normal (the standard (0, +-1, +-phi) coordinates), keeping those strictly
/// above the horizon (z > 1e-9). That orientation puts a great circle of 4 * 2^L vertices on the horizon, which are
/// excluded, so the count is icosahedron_hemisphere_count(level): 4, 17, 73, 305, 1249, ...
std::vector<Vec3d> icosahedron_directions(int level);

/// Count of icosahedron_directions(level): (10 * 4^L + 2 - 4 * 2^L) / 2 = 5 * 4^L - 2^(L+1) + 1.
std::size_t icosahedron_hemisphere_count(int level);

/// The normal plus `bands` rings at zenith k * zenith_max / bands (k = 1..bands), ring k holding
/// latlong_band_count(...) points evenly spaced in azimuth from azimuth 0.
std::vector<Vec3d> latlong_directions(int bands, double zenith_max_rad);

/// Points on ring k (1-based) of latlong_directions: max(1, round(2 pi sin(zenith_k) / dzenith)), dzenith =
/// zenith_max / bands, i.e. about the band spacing between neighbours along the ring.
int latlong_band_count(int band, int bands, double zenith_max_rad);

/// One point per cell of the equal-area grid u = (1 - cos zenith) / (1 - cos cap) in [0, 1) split into
/// `zenith_cells` rows, v = azimuth / 2 pi split into `azimuth_cells` columns; the point is uniformly jittered in
/// (u, v) inside its cell by a splitmix64 stream of `seed`. Row-major order (row = zenith cell).
std::vector<Vec3d> stratified_directions(int zenith_cells, int azimuth_cells, uint64_t seed, double cap_zenith_rad);

/// N points filling the cone of half-angle `cone_rad` around `centre` uniformly (a golden-angle spiral over the
/// cone's spherical cap, equal area per point). Points may fall below the horizon if the cone crosses it.
std::vector<Vec3d> dense_around_directions(const Vec3d& centre, double cone_rad, int count);

// --- From directions to pan/tilt targets. ---

/// A direction the stage can reach, with the pan/tilt that realises it. `index` is its place in the input list.
struct ViewTarget {
  std::size_t index = 0;
  Vec3d direction = Vec3d::UnitZ();
  PanTilt pan_tilt;
};

/// A direction no position within the axis limits gives.
struct UnreachableDirection {
  std::size_t index = 0;
  Vec3d direction = Vec3d::UnitZ();
};

struct TargetPlan {
  std::vector<ViewTarget> reachable;              // in input order
  std::vector<UnreachableDirection> unreachable;  // in input order; reachable.size() + unreachable.size() = input size
};

/// Runs rig::inverse_kinematics on every direction with the stage's axis limits. Nothing is dropped: each input
/// is in exactly one of the two lists. At the normal (pan free) `preferred_pan_rad` is kept.
TargetPlan plan_targets(const rig::RigGeometry& geometry, const rig::StageSpec& spec, std::span<const Vec3d> directions,
                        double preferred_pan_rad = 0.0);

}  // namespace vdrig::capture

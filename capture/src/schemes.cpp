#include "vdrig/capture/schemes.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <optional>
#include <utility>

#include "vdrig/core/log.hpp"
#include "vdrig/core/splitmix64.hpp"

namespace vdrig::capture {
namespace {

constexpr double kDuplicateTolerance = 1e-9;
constexpr double kHorizonTolerance = 1e-9;
constexpr int kMaxPoints = 100000;  // per component: keeps a typo from allocating gigabytes
constexpr int kMaxIcosahedronLevel = 6;
constexpr double kDefaultLatLongZenithMaxDeg = 80.0;

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t p = s.find(sep, start);
    parts.push_back(s.substr(start, p == std::string_view::npos ? std::string_view::npos : p - start));
    if (p == std::string_view::npos) return parts;
    start = p + 1;
  }
}

std::optional<double> parse_double(std::string_view s) {
  double v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

template <typename Int>
std::optional<Int> parse_int(std::string_view s) {
  Int v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

/// Degrees for the spec text: 12 significant digits hide the deg -> rad -> deg rounding (60 prints as 60, not
/// 59.99999999999999) and still round-trip any value typed with fewer digits.
std::string number(double v) {
  std::array<char, 64> buf{};
  const int n = std::snprintf(buf.data(), buf.size(), "%.12g", v);
  return std::string(buf.data(), static_cast<std::size_t>(std::max(0, n)));
}

Error bad_spec(std::string_view component, const std::string& why) {
  return make_error(ErrorCode::kInvalidArgument,
                    "sampling scheme component \"" + std::string(component) + "\": " + why);
}

Result<SchemeComponent> parse_component(std::string_view text) {
  const std::vector<std::string_view> f = split(text, ':');
  const std::string_view name = f[0];
  SchemeComponent c;
  auto want_fields = [&](std::size_t lo, std::size_t hi, const char* usage) -> std::optional<Error> {
    if (f.size() < lo || f.size() > hi) return bad_spec(text, std::string("expected ") + usage);
    return std::nullopt;
  };
  if (name == "spiral") {
    if (auto e = want_fields(3, 3, "spiral:N:R")) return *e;
    const auto n = parse_int<int>(f[1]);
    const auto r = parse_double(f[2]);
    if (!n) return bad_spec(text, "N must be an integer");
    if (!r) return bad_spec(text, "R (turns) must be a number");
    c.kind = SchemeKind::kSpiral;
    c.count = *n;
    c.turns = *r;
  } else if (name == "icosahedron") {
    if (auto e = want_fields(2, 2, "icosahedron:L")) return *e;
    const auto l = parse_int<int>(f[1]);
    if (!l) return bad_spec(text, "L (subdivision level) must be an integer");
    c.kind = SchemeKind::kIcosahedron;
    c.level = *l;
  } else if (name == "latlong") {
    if (auto e = want_fields(2, 3, "latlong:BANDS[:ZENITH_MAX_DEG]")) return *e;
    const auto b = parse_int<int>(f[1]);
    if (!b) return bad_spec(text, "BANDS must be an integer");
    c.kind = SchemeKind::kLatLong;
    c.bands = *b;
    if (f.size() == 3) {
      const auto z = parse_double(f[2]);
      if (!z) return bad_spec(text, "ZENITH_MAX_DEG must be a number");
      if (!(*z > 0.0)) return bad_spec(text, "ZENITH_MAX_DEG must be in (0, 90]");
      c.band_zenith_max_rad = deg_to_rad(*z);
    }
  } else if (name == "stratified") {
    if (auto e = want_fields(2, 3, "stratified:NZxNA[:SEED]")) return *e;
    const std::vector<std::string_view> dims = split(f[1], 'x');
    if (dims.size() != 2) return bad_spec(text, "grid must be written NZxNA, e.g. 16x16");
    const auto nz = parse_int<int>(dims[0]);
    const auto na = parse_int<int>(dims[1]);
    if (!nz || !na) return bad_spec(text, "grid sizes must be integers");
    c.kind = SchemeKind::kStratified;
    c.zenith_cells = *nz;
    c.azimuth_cells = *na;
    if (f.size() == 3) {
      const auto seed = parse_int<uint64_t>(f[2]);
      if (!seed) return bad_spec(text, "SEED must be a non-negative integer");
      c.seed = *seed;
    }
  } else if (name == "dense-around") {
    if (auto e = want_fields(4, 4, "dense-around:AZ_DEG,ZEN_DEG:CONE_DEG:N")) return *e;
    const std::vector<std::string_view> centre = split(f[1], ',');
    if (centre.size() != 2) return bad_spec(text, "centre must be written AZ_DEG,ZEN_DEG");
    const auto az = parse_double(centre[0]);
    const auto zen = parse_double(centre[1]);
    const auto cone = parse_double(f[2]);
    const auto n = parse_int<int>(f[3]);
    if (!az || !zen) return bad_spec(text, "centre azimuth and zenith must be numbers (degrees)");
    if (!cone) return bad_spec(text, "CONE_DEG must be a number");
    if (!n) return bad_spec(text, "N must be an integer");
    c.kind = SchemeKind::kDenseAround;
    c.centre_azimuth_rad = deg_to_rad(*az);
    c.centre_zenith_rad = deg_to_rad(*zen);
    c.cone_rad = deg_to_rad(*cone);
    c.count = *n;
  } else {
    return bad_spec(text, "unknown scheme \"" + std::string(name) +
                              "\" (expected spiral, icosahedron, latlong, stratified or dense-around)");
  }
  return c;
}

bool component_valid(const SchemeComponent& c, std::string* why) {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  const double quarter = kPi / 2.0 + 1e-12;
  switch (c.kind) {
    case SchemeKind::kSpiral:
      if (c.count < 1 || c.count > kMaxPoints) return fail("spiral: N must be 1.." + std::to_string(kMaxPoints));
      if (!(c.turns > 0.0) || c.turns > c.count) return fail("spiral: R (turns) must be in (0, N]");
      return true;
    case SchemeKind::kIcosahedron:
      if (c.level < 0 || c.level > kMaxIcosahedronLevel)
        return fail("icosahedron: L must be 0.." + std::to_string(kMaxIcosahedronLevel));
      return true;
    case SchemeKind::kLatLong:
      if (c.bands < 1 || c.bands > 180) return fail("latlong: BANDS must be 1..180");
      if (c.band_zenith_max_rad < 0.0 || c.band_zenith_max_rad > quarter)
        return fail("latlong: ZENITH_MAX_DEG must be in (0, 90]");
      return true;
    case SchemeKind::kStratified:
      if (c.zenith_cells < 1 || c.azimuth_cells < 1) return fail("stratified: grid sizes must be >= 1");
      if (static_cast<long long>(c.zenith_cells) * c.azimuth_cells > kMaxPoints)
        return fail("stratified: NZ * NA must be <= " + std::to_string(kMaxPoints));
      return true;
    case SchemeKind::kDenseAround:
      if (!(c.centre_azimuth_rad >= 0.0) || c.centre_azimuth_rad >= 2.0 * kPi)
        return fail("dense-around: AZ_DEG must be in [0, 360)");
      if (!(c.centre_zenith_rad >= 0.0) || c.centre_zenith_rad > quarter)
        return fail("dense-around: ZEN_DEG must be in [0, 90]");
      if (!(c.cone_rad > 0.0) || c.cone_rad > quarter) return fail("dense-around: CONE_DEG must be in (0, 90]");
      if (c.count < 1 || c.count > kMaxPoints) return fail("dense-around: N must be 1.." + std::to_string(kMaxPoints));
      return true;
  }
  return fail("unknown scheme kind");
}

double zenith_of(const Vec3d& d) { return std::acos(std::clamp(d.z(), -1.0, 1.0)); }

double latlong_zenith_max(const SchemeComponent& c, double global_max_rad) {
  return c.band_zenith_max_rad > 0.0 ? c.band_zenith_max_rad
                                     : std::min(deg_to_rad(kDefaultLatLongZenithMaxDeg), global_max_rad);
}

/// Indices of the directions to keep: each one not within kDuplicateTolerance of an earlier kept one.
std::vector<bool> first_occurrences(const std::vector<Vec3d>& d) {
  std::vector<std::size_t> by_x(d.size());
  std::iota(by_x.begin(), by_x.end(), std::size_t{0});
  std::sort(by_x.begin(), by_x.end(), [&](std::size_t a, std::size_t b) { return d[a].x() < d[b].x(); });
  // A point is dropped when any earlier point (in input order) lies within tolerance; a sweep over x sorted by x
  // keeps this O(n log n) for any reasonable input.
  std::vector<std::size_t> earliest(d.size());
  std::iota(earliest.begin(), earliest.end(), std::size_t{0});
  for (std::size_t a = 0; a < by_x.size(); ++a) {
    for (std::size_t b = a + 1; b < by_x.size(); ++b) {
      const std::size_t i = by_x[a], j = by_x[b];
      if (d[j].x() - d[i].x() > kDuplicateTolerance) break;
      if ((d[i] - d[j]).norm() <= kDuplicateTolerance) {
        earliest[i] = std::min(earliest[i], j);
        earliest[j] = std::min(earliest[j], i);
      }
    }
  }
  std::vector<bool> keep(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) keep[i] = earliest[i] == i;
  return keep;
}

}  // namespace

bool SamplingScheme::is_valid(std::string* why) const {
  if (components.empty()) {
    if (why) *why = "a sampling scheme needs at least one component";
    return false;
  }
  if (!(max_zenith_rad > 0.0) || max_zenith_rad > kPi / 2.0 + 1e-12) {
    if (why) *why = "the zenith limit (@MAX_ZENITH_DEG) must be in (0, 90]";
    return false;
  }
  for (const SchemeComponent& c : components)
    if (!component_valid(c, why)) return false;
  return true;
}

Result<SamplingScheme> parse_scheme(std::string_view spec_in) {
  std::string spec;
  for (char ch : spec_in)
    if (!std::isspace(static_cast<unsigned char>(ch))) spec.push_back(ch);
  if (spec.empty()) return make_error(ErrorCode::kInvalidArgument, "empty sampling scheme spec");
  SamplingScheme scheme;
  std::string_view body = spec;
  const std::size_t at = body.find('@');
  if (at != std::string_view::npos) {
    const std::string_view limit = body.substr(at + 1);
    const auto deg = parse_double(limit);
    if (!deg)
      return make_error(ErrorCode::kInvalidArgument,
                        "sampling scheme \"" + spec + "\": the zenith limit after '@' must be a number of degrees");
    if (!(*deg > 0.0) || *deg > 90.0)
      return make_error(ErrorCode::kInvalidArgument, "sampling scheme \"" + spec + "\": the zenith limit @" +
                                                         std::string(limit) + " must be in (0, 90] degrees");
    scheme.max_zenith_rad = deg_to_rad(*deg);
    body = body.substr(0, at);
  }
  for (std::string_view part : split(body, '+')) {
    if (part.empty())
      return make_error(ErrorCode::kInvalidArgument, "sampling scheme \"" + spec + "\": empty component");
    auto c = parse_component(part);
    if (!c) return c.error();
    std::string why;
    if (!component_valid(*c, &why)) return bad_spec(part, why);
    scheme.components.push_back(*c);
  }
  std::string why;
  if (!scheme.is_valid(&why))
    return make_error(ErrorCode::kInvalidArgument, "sampling scheme \"" + spec + "\": " + why);
  return scheme;
}

std::string to_spec(const SamplingScheme& s) {
  std::string out;
  for (const SchemeComponent& c : s.components) {
    if (!out.empty()) out += '+';
    switch (c.kind) {
      case SchemeKind::kSpiral:
        out += "spiral:" + std::to_string(c.count) + ":" + number(c.turns);
        break;
      case SchemeKind::kIcosahedron:
        out += "icosahedron:" + std::to_string(c.level);
        break;
      case SchemeKind::kLatLong:
        out += "latlong:" + std::to_string(c.bands);
        if (c.band_zenith_max_rad > 0.0) out += ":" + number(rad_to_deg(c.band_zenith_max_rad));
        break;
      case SchemeKind::kStratified:
        out += "stratified:" + std::to_string(c.zenith_cells) + "x" + std::to_string(c.azimuth_cells) + ":" +
               std::to_string(c.seed);
        break;
      case SchemeKind::kDenseAround:
        out += "dense-around:" + number(rad_to_deg(c.centre_azimuth_rad)) + "," +
               number(rad_to_deg(c.centre_zenith_rad)) + ":" + number(rad_to_deg(c.cone_rad)) + ":" +
               std::to_string(c.count);
        break;
    }
  }
  if (s.max_zenith_rad < kPi / 2.0) out += "@" + number(rad_to_deg(s.max_zenith_rad));
  return out;
}

std::vector<Vec3d> spiral_directions(int count, double turns, double cap_zenith_rad) {
  VDRIG_CHECK(count >= 1 && turns > 0.0 && cap_zenith_rad > 0.0, "spiral_directions: bad arguments");
  // Curve s in [0, 1]: zenith = s cap, azimuth = 2 pi R s. Arc length element
  //   dl = sqrt(cap^2 + (2 pi R sin(s cap))^2) ds,
  // integrated on a fine grid, then inverted by linear interpolation.
  const int steps = std::max(20000, 64 * count);
  const double w = 2.0 * kPi * turns;
  auto speed = [&](double s) { return std::hypot(cap_zenith_rad, w * std::sin(s * cap_zenith_rad)); };
  std::vector<double> arc(steps + 1, 0.0);
  for (int k = 1; k <= steps; ++k) {
    const double s0 = static_cast<double>(k - 1) / steps, s1 = static_cast<double>(k) / steps;
    arc[k] = arc[k - 1] + 0.5 * (speed(s0) + speed(s1)) * (s1 - s0);
  }
  std::vector<Vec3d> out;
  out.reserve(count);
  int k = 1;
  for (int i = 0; i < count; ++i) {
    const double target = (i + 0.5) / count * arc[steps];
    while (k < steps && arc[k] < target) ++k;
    const double f = (target - arc[k - 1]) / (arc[k] - arc[k - 1]);
    const double s = (k - 1 + f) / steps;
    out.push_back(direction_from_spherical(std::fmod(w * s, 2.0 * kPi), s * cap_zenith_rad));
  }
  return out;
}

std::vector<Vec3d> icosahedron_directions(int level) {
  VDRIG_CHECK(level >= 0 && level <= kMaxIcosahedronLevel, "icosahedron_directions: level out of range");
  const double p = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3d> v = {{-1, p, 0},  {1, p, 0},  {-1, -p, 0}, {1, -p, 0}, {0, -1, p},  {0, 1, p},
                          {0, -1, -p}, {0, 1, -p}, {p, 0, -1},  {p, 0, 1},  {-p, 0, -1}, {-p, 0, 1}};
  for (Vec3d& x : v) x.normalize();
  std::vector<std::array<int, 3>> faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                           {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                           {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                           {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      const int idx = static_cast<int>(v.size()) - 1;
      midpoint.emplace(key, idx);
      return idx;
    };
    std::vector<std::array<int, 3>> next;
    next.reserve(faces.size() * 4);
    for (const auto& f : faces) {
      const int ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
      next.push_back({f[0], ab, ca});
      next.push_back({f[1], bc, ab});
      next.push_back({f[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    faces = std::move(next);
  }
  std::vector<Vec3d> out;
  for (const Vec3d& x : v)
    if (x.z() > kHorizonTolerance) out.push_back(x);
  return out;
}

std::size_t icosahedron_hemisphere_count(int level) {
  VDRIG_CHECK(level >= 0 && level <= kMaxIcosahedronLevel, "icosahedron_hemisphere_count: level out of range");
  const std::size_t four_l = std::size_t{1} << (2 * level);
  const std::size_t two_l = std::size_t{1} << level;
  return 5 * four_l - 2 * two_l + 1;
}

int latlong_band_count(int band, int bands, double zenith_max_rad) {
  const double dz = zenith_max_rad / bands;
  const double zen = band * dz;
  return std::max(1, static_cast<int>(std::lround(2.0 * kPi * std::sin(zen) / dz)));
}

std::vector<Vec3d> latlong_directions(int bands, double zenith_max_rad) {
  VDRIG_CHECK(bands >= 1 && zenith_max_rad > 0.0, "latlong_directions: bad arguments");
  std::vector<Vec3d> out = {Vec3d::UnitZ()};
  for (int k = 1; k <= bands; ++k) {
    const double zen = k * zenith_max_rad / bands;
    const int n = latlong_band_count(k, bands, zenith_max_rad);
    for (int a = 0; a < n; ++a) out.push_back(direction_from_spherical(2.0 * kPi * a / n, zen));
  }
  return out;
}

std::vector<Vec3d> stratified_directions(int zenith_cells, int azimuth_cells, uint64_t seed, double cap_zenith_rad) {
  VDRIG_CHECK(zenith_cells >= 1 && azimuth_cells >= 1 && cap_zenith_rad > 0.0, "stratified_directions: bad arguments");
  SplitMix64 rng{seed};
  const double one_minus_cos_cap = 1.0 - std::cos(cap_zenith_rad);
  std::vector<Vec3d> out;
  out.reserve(static_cast<std::size_t>(zenith_cells) * azimuth_cells);
  for (int i = 0; i < zenith_cells; ++i) {
    for (int j = 0; j < azimuth_cells; ++j) {
      const double u = (i + rng.uniform()) / zenith_cells;
      const double v = (j + rng.uniform()) / azimuth_cells;
      const double cos_zen = 1.0 - u * one_minus_cos_cap;
      out.push_back(direction_from_spherical(2.0 * kPi * v, std::acos(std::clamp(cos_zen, -1.0, 1.0))));
    }
  }
  return out;
}

std::vector<Vec3d> dense_around_directions(const Vec3d& centre_in, double cone_rad, int count) {
  VDRIG_CHECK(count >= 1 && cone_rad > 0.0 && centre_in.norm() > 0.0, "dense_around_directions: bad arguments");
  const Vec3d c = centre_in.normalized();
  const Vec3d a = std::abs(c.x()) < 0.9 ? Vec3d::UnitX() : Vec3d::UnitY();
  const Vec3d e1 = (a - a.dot(c) * c).normalized();
  const Vec3d e2 = c.cross(e1);
  const double golden_angle = kPi * (3.0 - std::sqrt(5.0));
  const double one_minus_cos_cone = 1.0 - std::cos(cone_rad);
  std::vector<Vec3d> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) {
    const double cos_a = 1.0 - (i + 0.5) / count * one_minus_cos_cone;
    const double sin_a = std::sqrt(std::max(0.0, 1.0 - cos_a * cos_a));
    const double b = golden_angle * i;
    out.push_back((cos_a * c + sin_a * (std::cos(b) * e1 + std::sin(b) * e2)).normalized());
  }
  return out;
}

SampleSet generate(const SamplingScheme& scheme) {
  std::string why;
  VDRIG_CHECK(scheme.is_valid(&why), "generate: invalid sampling scheme: " + why);
  const double cap = scheme.max_zenith_rad;
  std::vector<Vec3d> all;
  for (const SchemeComponent& c : scheme.components) {
    std::vector<Vec3d> part;
    switch (c.kind) {
      case SchemeKind::kSpiral:
        part = spiral_directions(c.count, c.turns, cap);
        break;
      case SchemeKind::kIcosahedron:
        part = icosahedron_directions(c.level);
        break;
      case SchemeKind::kLatLong:
        part = latlong_directions(c.bands, latlong_zenith_max(c, cap));
        break;
      case SchemeKind::kStratified:
        part = stratified_directions(c.zenith_cells, c.azimuth_cells, c.seed, cap);
        break;
      case SchemeKind::kDenseAround:
        part = dense_around_directions(direction_from_spherical(c.centre_azimuth_rad, c.centre_zenith_rad), c.cone_rad,
                                       c.count);
        break;
    }
    all.insert(all.end(), part.begin(), part.end());
  }
  SampleSet out;
  std::vector<Vec3d> within;
  within.reserve(all.size());
  for (const Vec3d& d : all) {
    if (zenith_of(d) <= cap + 1e-9)
      within.push_back(d.normalized());
    else
      ++out.above_limit_removed;
  }
  const std::vector<bool> keep = first_occurrences(within);
  for (std::size_t i = 0; i < within.size(); ++i) {
    if (keep[i])
      out.directions.push_back(within[i]);
    else
      ++out.duplicates_removed;
  }
  if (out.above_limit_removed > 0 || out.duplicates_removed > 0)
    log::get("capture")->info("sampling scheme {}: {} directions ({} beyond the zenith limit, {} duplicates removed)",
                              to_spec(scheme), out.directions.size(), out.above_limit_removed, out.duplicates_removed);
  return out;
}

Result<SampleSet> generate(std::string_view spec) {
  auto scheme = parse_scheme(spec);
  if (!scheme) return scheme.error();
  return generate(*scheme);
}

TargetPlan plan_targets(const rig::RigGeometry& geometry, const rig::StageSpec& spec, std::span<const Vec3d> directions,
                        double preferred_pan_rad) {
  TargetPlan plan;
  for (std::size_t i = 0; i < directions.size(); ++i) {
    const Vec3d& d = directions[i];
    std::optional<PanTilt> pt;
    if (d.allFinite() && d.norm() > 0.0) pt = rig::inverse_kinematics(geometry, spec, d, preferred_pan_rad);
    if (pt)
      plan.reachable.push_back({i, d, *pt});
    else
      plan.unreachable.push_back({i, d});
  }
  if (!plan.unreachable.empty())
    log::get("capture")->warn("{} of {} view directions are out of the stage's reach", plan.unreachable.size(),
                              directions.size());
  return plan;
}

}  // namespace vdrig::capture

#include "vdrig/fitting/voronoi.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "vdrig/core/result.hpp"

namespace vdrig::fitting {
namespace {

constexpr double kHorizonTol = 1e-12;                  // |z| below this counts as on the horizon
constexpr double kCoincidentChord = 1e-9;              // samples closer than this (chord) share one cell
constexpr double kPlaneTol = 1e-13;                    // vertex within this of a clip plane counts as on it
constexpr double kVertexMergeChord = 1e-11;            // consecutive vertices closer than this are merged
constexpr double kMaxArcCos = 0.70710678118654752440;  // keep edges shorter than 45 degrees (cos > this)

// Inserts points along the great circle with normal `n` between a and b (both on it), travelling in the
// direction n x a (the counter-clockwise direction when the interior is on the n side), so no edge exceeds 45 deg.
void append_arc_subdivision(const Vec3d& a, const Vec3d& b, const Vec3d& n, std::vector<Vec3d>& out) {
  const Vec3d t = n.cross(a).normalized();
  double span = std::atan2(b.dot(t), b.dot(a));  // angle from a to b along t, in (-pi, pi]
  if (span < 0) span += 2.0 * kPi;
  const int pieces = static_cast<int>(std::ceil(span / (kPi / 4.0)));
  for (int k = 1; k < pieces; ++k) {
    const double ang = span * k / pieces;
    out.push_back((std::cos(ang) * a + std::sin(ang) * t).normalized());
  }
}

// Keeps the part of the convex spherical polygon `poly` (CCW, minor-arc edges) with q . n >= 0 (n unit).
std::vector<Vec3d> clip(const std::vector<Vec3d>& poly, const Vec3d& n) {
  const std::size_t count = poly.size();
  std::vector<double> d(count);
  bool any_out = false;
  for (std::size_t i = 0; i < count; ++i) {
    d[i] = poly[i].dot(n);
    any_out |= d[i] < -kPlaneTol;
  }
  if (!any_out) return poly;
  // Sutherland-Hodgman; remember which output vertices lie on the plane so new boundary arcs can be subdivided.
  std::vector<Vec3d> out;
  std::vector<char> on_plane;
  auto emit = [&](const Vec3d& v, bool on) {
    out.push_back(v);
    on_plane.push_back(on ? 1 : 0);
  };
  for (std::size_t i = 0; i < count; ++i) {
    const Vec3d& s = poly[(i + count - 1) % count];
    const Vec3d& e = poly[i];
    const double ds = d[(i + count - 1) % count];
    const double de = d[i];
    const bool s_in = ds >= -kPlaneTol;
    const bool e_in = de >= -kPlaneTol;
    if (e_in) {
      if (!s_in && de > kPlaneTol) emit((e * (-ds) + s * de).normalized(), true);  // entering
      emit(e, std::abs(de) <= kPlaneTol);
    } else if (s_in && ds > kPlaneTol) {
      emit((e * ds + s * (-de)).normalized(), true);  // leaving
    }
  }
  if (out.size() < 2) return out;
  // Edges from a vertex on the plane to the next one on the plane run along the new boundary: subdivide them.
  std::vector<Vec3d> result;
  result.reserve(out.size() + 8);
  for (std::size_t i = 0; i < out.size(); ++i) {
    const std::size_t j = (i + 1) % out.size();
    result.push_back(out[i]);
    if (on_plane[i] && on_plane[j] && out[i].dot(out[j]) < kMaxArcCos)
      append_arc_subdivision(out[i], out[j], n, result);
  }
  // Merge near-duplicate consecutive vertices (several bisectors through one Voronoi vertex, e.g. on grids).
  std::vector<Vec3d> merged;
  merged.reserve(result.size());
  for (const Vec3d& v : result) {
    if (merged.empty() || (v - merged.back()).norm() > kVertexMergeChord) merged.push_back(v);
  }
  while (merged.size() > 1 && (merged.front() - merged.back()).norm() <= kVertexMergeChord) merged.pop_back();
  return merged;
}

// The upper hemisphere as a polygon: the horizon with eight 45-degree edges, counter-clockwise seen from +z.
std::vector<Vec3d> hemisphere_polygon() {
  std::vector<Vec3d> poly;
  for (int k = 0; k < 8; ++k) poly.push_back(direction_from_spherical(k * kPi / 4.0, kPi / 2.0));
  return poly;
}

struct Prepared {
  std::vector<Vec3d> unit;          // normalised, horizon-snapped directions
  std::vector<int> representative;  // index of the first coincident participating sample, or -1 if not taking part
  std::vector<int> group_size;      // per representative: how many samples share its cell
};

Prepared prepare(const std::vector<Vec3d>& directions) {
  const int count = static_cast<int>(directions.size());
  Prepared p;
  p.unit.resize(count);
  p.representative.assign(count, -1);
  p.group_size.assign(count, 0);
  std::vector<int> reps;
  for (int i = 0; i < count; ++i) {
    const double norm = directions[i].norm();
    VDRIG_CHECK(norm > 0.0 && std::isfinite(norm), "hemisphere_voronoi_areas: zero or non-finite direction");
    Vec3d u = directions[i] / norm;
    if (u.z() < -kHorizonTol) continue;
    if (u.z() < 0.0) u = Vec3d(u.x(), u.y(), 0.0).normalized();
    p.unit[i] = u;
    int rep = i;
    for (int r : reps) {
      if ((p.unit[r] - u).norm() < kCoincidentChord) {
        rep = r;
        break;
      }
    }
    if (rep == i) reps.push_back(i);
    p.representative[i] = rep;
    ++p.group_size[rep];
  }
  return p;
}

std::vector<Vec3d> cell_of(const Prepared& p, int index) {
  const Vec3d& c = p.unit[index];
  // Other representatives ordered by increasing angle (decreasing dot product).
  std::vector<std::pair<double, int>> others;
  for (std::size_t j = 0; j < p.unit.size(); ++j) {
    if (p.representative[j] != static_cast<int>(j) || static_cast<int>(j) == index) continue;
    others.emplace_back(c.dot(p.unit[j]), static_cast<int>(j));
  }
  // Only the nearest few usually matter: order the first kFirst, and the rest only if the cell is still large.
  constexpr std::size_t kFirst = 32;
  auto nearer = [](const auto& a, const auto& b) { return a.first > b.first; };
  const std::size_t first = std::min(kFirst, others.size());
  std::partial_sort(others.begin(), others.begin() + first, others.end(), nearer);
  std::vector<Vec3d> poly = hemisphere_polygon();
  double min_vertex_dot = -1.0;  // cos of the angle from c to its farthest cell vertex
  for (std::size_t k = 0; k < others.size(); ++k) {
    if (k == first) std::sort(others.begin() + first, others.end(), nearer);
    const auto [dot, j] = others[k];
    // A sample at angle a can only cut the cell if a < 2 * (angle to the farthest vertex).
    if (min_vertex_dot > 0.0) {
      const double max_angle = std::acos(std::min(1.0, min_vertex_dot));
      if (std::acos(std::clamp(dot, -1.0, 1.0)) > 2.0 * max_angle + 1e-9) break;
    }
    const Vec3d n = (c - p.unit[j]).normalized();
    poly = clip(poly, n);
    VDRIG_CHECK(poly.size() >= 3, "hemisphere_voronoi_cell: cell degenerated while clipping");
    min_vertex_dot = 1.0;
    for (const Vec3d& v : poly) min_vertex_dot = std::min(min_vertex_dot, v.dot(c));
  }
  return poly;
}

}  // namespace

double spherical_polygon_area(const std::vector<Vec3d>& vertices) {
  const std::size_t count = vertices.size();
  if (count < 3) return 0.0;
  double turning = 0.0;
  for (std::size_t i = 0; i < count; ++i) {
    const Vec3d& u = vertices[(i + count - 1) % count];
    const Vec3d& v = vertices[i];
    const Vec3d& w = vertices[(i + 1) % count];
    const Vec3d t_in = u.cross(v).normalized().cross(v);
    const Vec3d t_out = v.cross(w).normalized().cross(v);
    turning += std::atan2(t_in.cross(t_out).dot(v), t_in.dot(t_out));
  }
  return 2.0 * kPi - turning;
}

std::vector<Vec3d> hemisphere_voronoi_cell(const std::vector<Vec3d>& directions, int index) {
  VDRIG_CHECK(index >= 0 && index < static_cast<int>(directions.size()), "hemisphere_voronoi_cell: bad index");
  const Prepared p = prepare(directions);
  const int rep = p.representative[index];
  if (rep < 0) return {};
  return cell_of(p, rep);
}

std::vector<double> hemisphere_voronoi_areas(const std::vector<Vec3d>& directions) {
  const Prepared p = prepare(directions);
  std::vector<double> areas(directions.size(), 0.0);
  for (std::size_t i = 0; i < directions.size(); ++i) {
    if (p.representative[i] != static_cast<int>(i)) continue;
    areas[i] = spherical_polygon_area(cell_of(p, static_cast<int>(i))) / p.group_size[i];
  }
  for (std::size_t i = 0; i < directions.size(); ++i) {
    const int rep = p.representative[i];
    if (rep >= 0 && rep != static_cast<int>(i)) areas[i] = areas[rep];
  }
  return areas;
}

}  // namespace vdrig::fitting

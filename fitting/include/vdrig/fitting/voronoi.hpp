// Spherical Voronoi areas of sample directions on the upper hemisphere (z >= 0 of the surface frame).
//
// The SH projections of the source (ZH, LSOP) are quadratures: c = sum_j f(s_j) y(s_j) dA_j, where dA_j is the
// solid angle of the region of the hemisphere closer (in angle) to sample j than to any other sample. This file
// computes those dA_j exactly (up to rounding): the cells of a true geodesic Voronoi partition of the upper
// hemisphere, clipped at the horizon, so sum_j dA_j = 2 pi.
//
// Why not the source's planar construction (drop z, planar Voronoi in the unit disc, weight each cell by
// 1 / cos(zenith of its sample)): the orthographic projection's Jacobian 1/cos(zenith) varies strongly across a
// cell near the horizon and diverges at it (it is 1/sqrt(1 - r^2) in the disc), so one point evaluation at the
// sample does not give the cell's solid angle; cells touching the unit circle are badly under- or over-estimated
// (the source's residuals of up to 40 % near the equator). Moreover, the Euclidean bisectors in the disc are not
// the projections of the geodesic bisectors, so even the cell shapes are wrong there. Near the zenith both agree.
//
// Construction: the cell of sample p is the intersection of the upper hemisphere with the half-spaces
// {q : q . (p - p_j) >= 0} over all other samples p_j. This is the same partition as the Voronoi diagram of the
// samples plus their mirror images below the horizon (for q above the horizon, p_j is always nearer than its
// mirror, and the bisector of p and its own mirror is the horizon), without building a convex hull. Each cell is a
// convex spherical polygon obtained by Sutherland-Hodgman clipping of the hemisphere (edges kept shorter than
// 90 degrees so every arc is unambiguous); neighbours are visited in order of increasing angle and clipping stops
// once no farther sample can cut the cell (a sample at angle a from p cannot cut a cell whose farthest vertex is
// closer than a/2). A set of N directions costs O(N^2) dot products plus O(N k) clips, k the neighbour count. Areas
// come from Gauss-Bonnet (2 pi minus the sum of turning angles), which needs no interior point and also holds for the
// whole hemisphere.
#pragma once

#include <vector>

#include "vdrig/core/geometry.hpp"

namespace vdrig::fitting {

/// Solid angle (sr) of each sample's Voronoi cell on the upper hemisphere.
///
/// Contract:
///  - `directions` need not be normalised (they are normalised here) but must be non-zero;
///  - samples strictly below the horizon (z < -1e-12 after normalisation) get area 0 and do not take part;
///  - samples on the horizon (|z| <= 1e-12) are legitimate; their cells are clipped at the horizon;
///  - coincident directions (angle < ~1e-9 rad) share their common cell equally, so the areas still sum to 2 pi;
///  - with no sample above or on the horizon, all areas are 0.
/// The areas of the participating samples sum to 2 pi (to ~1e-12 relative).
std::vector<double> hemisphere_voronoi_areas(const std::vector<Vec3d>& directions);

/// The Voronoi cell of sample `index` as an ordered (counter-clockwise seen from outside) list of unit vertex
/// vectors; for inspection and tests. Empty for samples that do not take part (see above).
std::vector<Vec3d> hemisphere_voronoi_cell(const std::vector<Vec3d>& directions, int index);

/// Solid angle of a simple spherical polygon with unit vertices in counter-clockwise order (seen from outside)
/// whose edges are minor arcs: 2 pi minus the sum of the signed turning angles (Gauss-Bonnet).
double spherical_polygon_area(const std::vector<Vec3d>& vertices);

}  // namespace vdrig::fitting

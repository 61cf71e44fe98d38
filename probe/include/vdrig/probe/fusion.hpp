// Fusing several light probes on proxy geometry (Madsen-style "multiple light probes", the fusing thesis' §5.1-5.2,
// docs/probe.md "Fusing probes"): every probe's pixels are placed on a rough model of the scene (an axis-aligned
// room, `ProxyBox`), and the radiance arriving at a new position is looked up, per direction, in every probe that
// sees the same scene point, then blended.
//
// World frame, millimetres. A probe's pixel direction d_probe is d_world = rotation * d_probe (probe.hpp); the maps
// produced here are world-aligned (rotation identity) and carry the proxy depth seen from their position.
#pragma once

#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

/// Axis-aligned room: the proxy geometry is its six walls, seen from inside.
struct ProxyBox {
  Vec3d min_mm = Vec3d::Zero();
  Vec3d max_mm = Vec3d::Zero();

  /// False with the reason unless min < max on every axis (finite).
  bool is_valid(std::string* why = nullptr) const;
  /// True when p lies strictly inside, at least margin_mm from every wall.
  bool contains(const Vec3d& p_mm, double margin_mm = 0) const;
};

/// Sphere proxy (a dome: the scene as a sphere around the probes), seen from inside.
struct ProxySphere {
  Vec3d centre_mm = Vec3d::Zero();
  double radius_mm = 0;
};

/// Where a ray leaving an interior point meets the proxy.
struct ProxyHit {
  bool hit = false;        // false when the origin is not strictly inside or the direction is zero
  double distance_mm = 0;  // along the unit direction
  Vec3d point_mm = Vec3d::Zero();
  Vec3d normal = Vec3d::Zero();  // unit, the wall's normal pointing into the room (toward the origin's side)
};

/// Exit point of the ray origin + t dir (t > 0; dir any non-zero length) through the box's walls.
ProxyHit intersect_from_inside(const ProxyBox& box, const Vec3d& origin_mm, const Vec3d& dir);
/// Same for the sphere (inward normal = (centre - point) / radius).
ProxyHit intersect_from_inside(const ProxySphere& sphere, const Vec3d& origin_mm, const Vec3d& dir);

/// Distance (mm) from the probe's position to the proxy along every pixel's centre direction (rotated to the
/// world), as a CV_32FC1 map of the probe's size (what Probe::depth_mm holds). Pixels whose ray misses (probe not
/// inside the proxy) get 0.
cv::Mat proxy_depth(const Probe& probe, const ProxyBox& box);
cv::Mat proxy_depth(const Probe& probe, const ProxySphere& sphere);

/// How probes are weighted when fused (see fuse()). Validated once by is_valid.
struct FusionOptions {
  /// Largest `height`: a 16384 x 8192 RGB float map with its depth and weights is about 2 GB.
  static constexpr int kMaxHeight = 8192;
  /// Rows of the fused map (width twice that); 0 keeps the probes' height. At most kMaxHeight.
  int height = 0;
  /// Angular agreement weight ((1 + w . w_i) / 2)^angular_exponent, where w is the direction from the scene point
  /// to the new position and w_i the direction from the point to probe i (the thesis' eq. 5.5 orders probes by
  /// w . w_i; remapped to [0, 1] so that a point seen only from a poor angle still gets a value). 0 disables it.
  double angular_exponent = 1.0;
  /// Probes with w . w_i below this are dropped for that point (the thesis' user threshold); -1 keeps all.
  double min_cosine = -1.0;
  /// Sampling-density weight min(1, rho)^resolution_exponent, rho = (d^2 cos a_i) / (d_i^2 cos a): how densely
  /// probe i's pixels cover the wall around the point (distance d_i, incidence a_i from the wall normal) compared
  /// with the new map's pixels (d, a). A distant or grazing probe sees the point through a blurred pixel. 0 disables.
  double resolution_exponent = 4.0;
  /// A scene point closer than this to a probe's centre is not used from that probe (the point is "behind" or
  /// inside the probe; its direction is ill-defined).
  double min_distance_mm = 10.0;
  /// Visibility (the thesis' eq. 5.4, shadow-map style): a probe with depth_mm does not see the point when the
  /// point is farther than its stored depth in that direction by more than this fraction (the largest depth of the
  /// four nearest pixels is used, so that depth edges do not hide visible points).
  double occlusion_tolerance = 0.02;

  /// False with the reason for a negative height or one above kMaxHeight, negative exponents, min_cosine outside [-1,
  /// 1), a non-positive min distance or a negative tolerance.
  bool is_valid(std::string* why = nullptr) const;
};

/// One probe seen from a new position: for each pixel of a `height` x 2 `height` map at new_position_mm
/// (world-aligned), the ray is intersected with the proxy, the wall point looked up in the source (direction from
/// the source's position through its rotation, bilinear) and weighted by the source's fusion weight there:
///   weight = V * [w . w_i >= min_cosine] * ((1 + w . w_i) / 2)^angular_exponent * min(1, rho)^resolution_exponent,
/// V = 0 when the point is behind the wall seen from the source (source outside the room), nearer than
/// min_distance_mm to it, or occluded according to the source's depth_mm (when it has one). Pixels with weight 0
/// are black. The result's depth_mm is the proxy depth from the new position. `weight` (optional) receives the
/// CV_32FC1 weights. Preconditions (VDRIG_CHECKed): box valid, height >= 1, options valid.
Probe reproject(const Probe& source, const Vec3d& new_position_mm, const ProxyBox& box, int height,
                cv::Mat* weight = nullptr, const FusionOptions& options = {});

/// What fuse() did, for logs and tests.
struct FusionStats {
  std::vector<double> weight_share;  // per probe: its share of the summed weight over the map (solid-angle weighted)
  int uncovered_pixels = 0;          // pixels no probe sees (filled from the nearest probe, see fuse())
  double uncovered_sr = 0;           // their solid angle
};

/// The radiance map at position_mm fused from `probes`: per pixel sum_i weight_i L_i / sum_i weight_i over the
/// reprojections (reproject() with `options`). A pixel no probe sees (all weights 0: points hidden from every probe,
/// or too near to all of them) falls back to the probe nearest to position_mm looked up along the same direction
/// without reprojection (the distant-scene assumption of ordinary IBL), and is counted in stats->uncovered_*.
/// Errors (kInvalidArgument): invalid options or box, no probes, empty or differently sized maps, position_mm or a
/// probe position not strictly inside the box.
Result<Probe> fuse(const std::vector<Probe>& probes, const Vec3d& position_mm, const ProxyBox& box,
                   const FusionOptions& options = {}, FusionStats* stats = nullptr);

/// What fuse() checks before it starts, but the position: kInvalidArgument for invalid options or box, no probes,
/// maps not 2:1 CV_32FC3 or of different sizes, a depth map of another size or type, a probe not strictly inside.
Status validate_fusion_inputs(const std::vector<Probe>& probes, const ProxyBox& box, const FusionOptions& options);

/// Index of the probe nearest to position_mm (fuse()'s fallback); `probes` must not be empty.
size_t nearest_probe(const std::vector<Probe>& probes, const Vec3d& position_mm);

/// The fused radiance arriving at position_mm from direction `dir` (world, any non-zero length): what fuse() gives a
/// pixel looking that way, sum_i weight_i L_i / sum_i weight_i with reproject()'s weights, or the nearest probe's
/// radiance along dir when no probe sees the wall point. `weight_sum` (optional) receives sum_i weight_i (0 for the
/// fallback). Inputs are not validated (fuse_cube does that once); VDRIG_CHECKs a non-empty `probes`.
Rgb fused_radiance(const std::vector<Probe>& probes, const Vec3d& position_mm, const ProxyBox& box, const Vec3d& dir,
                   const FusionOptions& options = {}, double* weight_sum = nullptr);

/// The CPU reference of the GPU fusion (probe_gl/gpu_fusion.hpp): a world-aligned cube of `size` at position_mm whose
/// texel (i, j) holds fused_radiance along its centre direction (cube_direction(face, i + 0.5, j + 0.5)).
/// `options.height` is ignored. Errors as fuse(), and kInvalidArgument for size < 1. `uncovered_texels` (optional)
/// receives the number of texels filled by the fallback.
Result<CubeMap> fuse_cube(const std::vector<Probe>& probes, const Vec3d& position_mm, const ProxyBox& box, int size,
                          const FusionOptions& options = {}, int* uncovered_texels = nullptr);

}  // namespace vdrig::probe

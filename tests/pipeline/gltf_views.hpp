// The sample, held-out views and per-region comparison shared by the tests that render vdrig's glTF export with a
// peer renderer (test_gltf_three.cpp: three.js; tests/fidelity/test_gltf_blender.cpp: Blender's importer and
// Cycles). A simulated bumped GGX plastic is observed from icosahedron:3@85 through the 8-bit camera, fitted with
// ggx:iso+n and exported; a peer's image of a held-out view is compared, pixel by pixel on the sample, with the
// simulator's radiance there (the "photograph") and with the fitted map's own radiance (ParameterMap::evaluate at the
// pixel's texel), as region means in 8-bit codes (the view's brightest true pixel at 220 codes), 4 x 4 regions.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <vector>

#include "../fitting/rig_observations.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/gltf_export.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/texel_recording.hpp"

namespace vdrig::pipeline::gltf_views {

/// glTF's frame (Y up) from the surface frame (z up): (x, y, z) -> (x, z, -y); and back. Blender's importer maps
/// glTF back to Z up the same way (from_gltf), so Blender's frame is the surface frame.
inline Vec3d to_gltf(const Vec3d& s) { return {s.x(), s.z(), -s.y()}; }
inline Vec3d from_gltf(const Vec3d& g) { return {g.x(), -g.z(), g.y()}; }

struct View {
  Vec3d eye_m;  // surface frame, metres
  double fov_y_deg;
};

/// Per-region mean differences in codes of one view: worst and mean over the regions that hold pixels.
struct RegionDiff {
  double worst = 0, mean = 0;
};

constexpr int kSize = 96, kRegions = 4, kTexels = 24;

/// The sample: the `bands` surface (1 x 1 m, one point light) of one bumped GGX plastic, 24 x 24 texels, fitted.
struct FittedSample {
  sim::Scene scene;
  fitting::SessionLight light;
  std::optional<fitting::ParameterMap> map;
};

inline FittedSample fit_bumped_plastic() {
  FittedSample out;
  sim::Scene& scene = out.scene;
  scene = sim::make_scene("bands").value();
  sim::Material plastic{"plastic", Vec3d(0.6, 0.25, 0.1)};
  plastic.kind = sim::MaterialKind::kGgx;
  plastic.roughness = 0.2;
  plastic.f0 = Vec3d::Constant(0.04);
  plastic.bump_slope = 0.3;
  plastic.bump_period_mm = 400.0;
  scene.materials = {plastic};
  scene.patches.clear();
  scene.markers.clear();
  const int S = kTexels;
  const std::vector<Vec3d> scheme = fitting::test_support::scheme_directions("icosahedron:3@85");
  fitting::ObservationMap obs({S, S, scene.width_mm, scene.height_mm}, static_cast<int>(scheme.size()));
  for (int t = 0; t < S; ++t)
    for (int s = 0; s < S; ++s) {
      fitting::TexelObservations texel = fitting::test_support::observe_texel(
          scene, texel_centre_mm(s, t, S, S, scene.width_mm, scene.height_mm), scheme);
      sim::record_texel(texel.radiance, {}, 9000u + static_cast<unsigned>(t * S + s));
      for (size_t v = 0; v < texel.size(); ++v)
        obs.set(s, t, static_cast<int>(v), texel.radiance[v], texel.direction[v], fitting::kObsValid);
    }
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("ggx:iso+n").value();
  options.threads = 2;
  out.light = session_light_of(scene).value();
  options.model_options.edit<fitting::GgxFitOptions>().light = out.light;
  auto map = fitting::fit_parameter_map(obs, options);
  EXPECT_TRUE(map) << map.error().describe();
  if (map) out.map = std::move(*map);
  return out;
}

/// Held-out views: none is a scheme direction (the nearest is several degrees away), one near the light's mirror
/// direction (the highlight), 2.5 m from the sample's centre, looking at it with glTF's -Z (the surface's +y) up.
inline std::vector<View> held_out_views() {
  auto eye = [](double zenith_deg, double azimuth_deg) -> Vec3d {
    return 2.5 * direction_from_spherical(deg_to_rad(azimuth_deg), deg_to_rad(zenith_deg));
  };
  return {{eye(33.0, 217.0), 28.0}, {eye(52.0, 100.0), 28.0}, {eye(18.0, 301.0), 28.0}};
}

/// The camera's axes in glTF's frame as three.js's lookAt builds them: z from the target to the eye, x = up x z,
/// y = z x x, with up = (0, 0, -1).
struct CameraAxes {
  Vec3d x, y, z;
};
inline CameraAxes camera_axes(const View& v) {
  const Vec3d zc = to_gltf(v.eye_m).normalized();
  const Vec3d xc = Vec3d(0, 0, -1).cross(zc).normalized();
  return {xc, zc.cross(xc), zc};
}

/// One view's comparison: peer vs photo, fit vs photo, peer vs fit; and the peer's total over the photo's.
struct ViewComparison {
  RegionDiff peer_truth, map_truth, peer_map;
  Vec3d ratio = Vec3d::Zero();
  int regions = 0;
};

/// `pixels`: the peer's linear RGBA image of `v`, kSize x kSize, bottom row first.
inline ViewComparison compare_view(const FittedSample& sample, const View& v, const std::vector<float>& pixels) {
  ViewComparison out;
  const sim::Scene& scene = sample.scene;
  const int S = kTexels;
  EXPECT_EQ(pixels.size(), static_cast<size_t>(kSize * kSize * 4));
  if (pixels.size() != static_cast<size_t>(kSize * kSize * 4) || !sample.map) return out;
  const Vec3d e = to_gltf(v.eye_m);
  const CameraAxes axes = camera_axes(v);
  const double tan_half = std::tan(deg_to_rad(v.fov_y_deg) / 2.0);
  constexpr int kCells = kRegions * kRegions;
  std::vector<Vec3d> sum_peer(kCells, Vec3d::Zero()), sum_truth(kCells, Vec3d::Zero()), sum_map(kCells, Vec3d::Zero());
  std::vector<int> count(kCells, 0);
  double brightest = 0;
  Vec3d total_peer = Vec3d::Zero(), total_truth = Vec3d::Zero();
  for (int j = 0; j < kSize; ++j)  // j = 0: the bottom row
    for (int i = 0; i < kSize; ++i) {
      const double x = (2.0 * (i + 0.5) / kSize - 1.0) * tan_half, y = (2.0 * (j + 0.5) / kSize - 1.0) * tan_half;
      Vec3d ray = x * axes.x;
      ray += y * axes.y;
      ray -= axes.z;
      ray.normalize();
      if (ray.y() >= 0) continue;
      const Vec3d hit = e + ray * (-e.y() / ray.y());
      const Vec3d p_mm = 1000.0 * from_gltf(hit);
      // Whole pixels inside the sample, away from its edge (texture clamping, partial pixels).
      const double margin = 0.02 * scene.width_mm;
      if (std::abs(p_mm.x()) > scene.width_mm / 2 - margin || std::abs(p_mm.y()) > scene.height_mm / 2 - margin)
        continue;
      const Vec3d to_eye = (v.eye_m * 1000.0 - p_mm).normalized();
      const Vec3d truth = scene.radiance(Vec3d(p_mm.x(), p_mm.y(), 0.0), to_eye);
      const int s = std::clamp(static_cast<int>((p_mm.x() / scene.width_mm + 0.5) * S), 0, S - 1);
      const int t = std::clamp(static_cast<int>((p_mm.y() / scene.height_mm + 0.5) * S), 0, S - 1);
      const Vec3d fitted = sample.map->evaluate(s, t, to_eye);
      const size_t at = 4 * (static_cast<size_t>(j) * kSize + static_cast<size_t>(i));
      const Vec3d peer(pixels[at], pixels[at + 1], pixels[at + 2]);
      const int ri = std::clamp(static_cast<int>((p_mm.x() / scene.width_mm + 0.5) * kRegions), 0, kRegions - 1);
      const int rj = std::clamp(static_cast<int>((p_mm.y() / scene.height_mm + 0.5) * kRegions), 0, kRegions - 1);
      const size_t cell = static_cast<size_t>(ri * kRegions + rj);
      sum_peer[cell] += peer, sum_truth[cell] += truth, sum_map[cell] += fitted;
      ++count[cell];
      brightest = std::max(brightest, truth.maxCoeff());
      total_peer += peer, total_truth += truth;
    }
  EXPECT_GT(brightest, 0.0);
  if (brightest <= 0.0) return out;
  const double codes = 220.0 / brightest;
  for (size_t cell = 0; cell < static_cast<size_t>(kCells); ++cell) {
    if (count[cell] < 20) continue;
    ++out.regions;
    const double n = count[cell];
    const Vec3d ta = (sum_peer[cell] - sum_truth[cell]) / n, tb = (sum_map[cell] - sum_truth[cell]) / n,
                tc = (sum_peer[cell] - sum_map[cell]) / n;
    const double a = codes * ta.cwiseAbs().maxCoeff(), b = codes * tb.cwiseAbs().maxCoeff(),
                 c = codes * tc.cwiseAbs().maxCoeff();
    out.peer_truth.worst = std::max(out.peer_truth.worst, a), out.peer_truth.mean += a;
    out.map_truth.worst = std::max(out.map_truth.worst, b), out.map_truth.mean += b;
    out.peer_map.worst = std::max(out.peer_map.worst, c), out.peer_map.mean += c;
  }
  EXPECT_GE(out.regions, 12) << "the view sees too little of the sample";
  if (out.regions > 0)
    for (RegionDiff* r : {&out.peer_truth, &out.map_truth, &out.peer_map}) r->mean /= out.regions;
  out.ratio = total_peer.cwiseQuotient(total_truth);
  return out;
}

/// Prints one view's figures (`peer`: the renderer's name).
inline void print_comparison(const char* peer, size_t view, bool negated, const ViewComparison& c) {
  std::printf(
      "view %zu%s: region mean |difference| in codes (worst / mean over %d regions): %s vs photo %.2f / %.2f, "
      "fit vs photo %.2f / %.2f, %s vs fit %.2f / %.2f\n",
      view, negated ? " (green negated)" : "", c.regions, peer, c.peer_truth.worst, c.peer_truth.mean,
      c.map_truth.worst, c.map_truth.mean, peer, c.peer_map.worst, c.peer_map.mean);
  std::printf("  %s / photo over the sample: %.4f %.4f %.4f (R G B)\n", peer, c.ratio.x(), c.ratio.y(), c.ratio.z());
}

}  // namespace vdrig::pipeline::gltf_views

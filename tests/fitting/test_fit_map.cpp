// Whole-map fitting (fit_parameter_map) on synthetic observation maps with known per-texel truth: every model,
// phong:auto's lobe choice, held-out views, and the parameter map's evaluate / write / read round trip.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/harmonic_model.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::fitting {
namespace {

constexpr int kS = 4, kT = 3;
constexpr double kSizeMm = 800.0, kDistanceMm = 2500.0;

/// Camera centres of a 17 x 17 pan/tilt grid to +-80 degrees at 2500 mm: the rig's 289 views.
std::vector<Vec3d> camera_centres() {
  std::vector<Vec3d> c;
  for (int i = 0; i < 17; ++i)
    for (int j = 0; j < 17; ++j) {
      const double pan = deg_to_rad(-80.0 + 10.0 * i), tilt = deg_to_rad(-80.0 + 10.0 * j);
      c.push_back(kDistanceMm * Vec3d(std::cos(tilt) * std::sin(pan), std::sin(tilt), std::cos(tilt) * std::cos(pan)));
    }
  return c;
}

/// An observation map whose texel (s, t) sees `truth(s, t, direction)` from every camera (each texel its own
/// directions, as at a finite distance).
template <typename Truth>
ObservationMap make_map(const Truth& truth) {
  ObservationMapSpec spec;
  spec.texels_s = kS;
  spec.texels_t = kT;
  spec.width_mm = spec.height_mm = kSizeMm;
  const auto centres = camera_centres();
  ObservationMap map(spec, static_cast<int>(centres.size()));
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      const Vec3d p = texel_centre_mm(s, t, kS, kT, kSizeMm, kSizeMm);
      for (size_t v = 0; v < centres.size(); ++v) {
        const Vec3d d = (centres[v] - p).normalized();
        map.set(s, t, static_cast<int>(v), truth(s, t, d).template cast<float>(), d.cast<float>(), kObsValid);
      }
    }
  return map;
}

PhongParams texel_phong(int s, int t, bool second_lobe) {
  PhongParams p;
  p.kd = Vec3d(0.2 + 0.05 * s, 0.1 + 0.03 * t, 0.05);
  PhongLobe l;
  l.ks = Vec3d(1.0, 0.8 + 0.1 * s, 0.6);
  l.direction = direction_from_spherical(deg_to_rad(30.0 + 40.0 * s), deg_to_rad(20.0 + 5.0 * t));
  l.shininess = 40.0 + 20.0 * t;
  p.lobes.push_back(l);
  if (second_lobe) {
    l.ks *= 0.5;
    l.direction = direction_from_spherical(deg_to_rad(210.0 + 40.0 * s), deg_to_rad(35.0));
    p.lobes.push_back(l);
  }
  return p;
}

MapFitOptions options_for(const std::string& spec) {
  MapFitOptions o;
  o.model = parse_model(spec).value();
  o.threads = 2;
  return o;
}

TEST(FitMap, PhongMapRecoversEveryTexel) {
  const ObservationMap obs =
      make_map([](int s, int t, const Vec3d& d) { return texel_phong(s, t, false).evaluate(d); });
  auto map = fit_parameter_map(obs, options_for("phong:1"));
  ASSERT_TRUE(map) << map.error().describe();
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      const PhongParams truth = texel_phong(s, t, false), fit = phong_texel(*map, s, t);
      EXPECT_LT((fit.kd - truth.kd).norm(), 1e-3);
      EXPECT_LT(rad_to_deg(angle_between(fit.lobes[0].direction, truth.lobes[0].direction)), 0.05);
      EXPECT_NEAR(fit.lobes[0].shininess, truth.lobes[0].shininess, 0.01 * truth.lobes[0].shininess);
      EXPECT_EQ(map->at("n", s, t), 289.0f);
      EXPECT_LT(map->at("rms.G", s, t), 1e-4);
      EXPECT_FALSE(map->has("holdout.R"));
    }
}

// phong:auto chooses two lobes where there are two, one where there is one; the map stores two.
TEST(FitMap, PhongAutoChoosesTheLobeCountPerTexel) {
  auto two = [](int s, int t) { return (s + t) % 2 == 0; };
  // Independent additive noise (sigma 0.003, ~1 % of the diffuse level) per observation and channel, so that the
  // BIC compares fits on noisy data with the noise model it assumes (make_map calls in a fixed order).
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.003);
  const ObservationMap obs = make_map([&](int s, int t, const Vec3d& d) {
    const Vec3d v = texel_phong(s, t, two(s, t)).evaluate(d);
    return Vec3d(v.x() + noise(rng), v.y() + noise(rng), v.z() + noise(rng));
  });
  auto map = fit_parameter_map(obs, options_for("phong:auto"));
  ASSERT_TRUE(map) << map.error().describe();
  const auto* model = dynamic_cast<const PhongModel*>(&map->model());
  ASSERT_NE(model, nullptr);
  EXPECT_EQ(model->lobes(), 2);
  EXPECT_TRUE(model->auto_lobes());
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      const PhongParams truth = texel_phong(s, t, two(s, t));
      ASSERT_EQ(map->at("lobes", s, t), static_cast<float>(truth.lobes.size())) << s << "," << t;
      const PhongParams fit = phong_texel(*map, s, t);
      for (const auto& tl : truth.lobes) {
        double best = 1e9;
        for (const auto& fl : fit.lobes)
          if (fl.ks.maxCoeff() > 0) best = std::min(best, rad_to_deg(angle_between(fl.direction, tl.direction)));
        EXPECT_LT(best, 1.0);
      }
      if (truth.lobes.size() == 1) {
        EXPECT_EQ(fit.lobes[1].ks, Vec3d::Zero());
      }
    }
  // Round trip through the file keeps the auto flag, the lobe count and the values.
  const test::TempDir dir("fit_map_auto");
  const auto path = dir / "map.exr";
  ASSERT_TRUE(map->write(path).is_ok());
  auto back = ParameterMap::read(path);
  ASSERT_TRUE(back) << back.error().describe();
  const auto* back_model = dynamic_cast<const PhongModel*>(&back->model());
  ASSERT_NE(back_model, nullptr);
  EXPECT_EQ(back_model->lobes(), 2);
  EXPECT_TRUE(back_model->auto_lobes());
  const Vec3d v = Vec3d(0.3, -0.2, 0.9).normalized();
  EXPECT_LT((back->evaluate(1, 1, v) - map->evaluate(1, 1, v)).norm(), 1e-6);
}

/// RMS of a map texel's model against a set of observations, by ParameterMap::evaluate.
Vec3d rms_by_evaluate(const ParameterMap& map, int s, int t, const TexelObservations& obs) {
  Vec3d sq = Vec3d::Zero();
  for (size_t i = 0; i < obs.size(); ++i) {
    const Vec3d r = map.evaluate(s, t, obs.direction[i].cast<double>()) - obs.radiance[i].cast<double>();
    sq += r.cwiseProduct(r);
  }
  return (sq / static_cast<double>(obs.size())).cwiseSqrt();
}

// A band-limited function is reproduced exactly by least squares in its own basis (SH-LS, HSH), and every linear
// model's quality channels agree with ParameterMap::evaluate on the observations.
TEST(FitMap, LinearModelsReproduceBandLimitedTexelsAndTheirQuality) {
  constexpr int kBands = 4;
  auto coeffs = [](int s, int t) {
    Eigen::MatrixXd c(sh_coeff_count(kBands), 3);
    for (int i = 0; i < c.rows(); ++i)
      for (int ch = 0; ch < 3; ++ch) c(i, ch) = (i == 0 ? 2.0 : 0.3 * std::sin(1.7 * i + ch + s - 0.5 * t));
    return c;
  };
  for (const std::string kind : {"sh-ls", "hsh", "sh-zh", "sh-lsop"}) {
    SCOPED_TRACE(kind);
    const bool hsh = kind == "hsh";
    const ObservationMap obs = make_map([&](int s, int t, const Vec3d& d) {
      return hsh ? Vec3d(eval_hsh(coeffs(s, t), d)) : Vec3d(eval_sh(coeffs(s, t), d));
    });
    auto map = fit_parameter_map(obs, options_for(kind + ":" + std::to_string(kBands)));
    ASSERT_TRUE(map) << map.error().describe();
    for (int t = 0; t < kT; ++t)
      for (int s = 0; s < kS; ++s) {
        const TexelObservations texel = obs.texel(s, t);
        const Vec3d rms = rms_by_evaluate(*map, s, t, texel);
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(map->at(std::string("rms.") + "RGB"[c], s, t), rms[c], 1e-5 + 1e-4 * rms[c]);
        EXPECT_EQ(map->at("n", s, t), 289.0f);
        if (kind == "sh-ls" || kind == "hsh") {
          EXPECT_LT((harmonic_coefficients(*map, s, t) - coeffs(s, t)).cwiseAbs().maxCoeff(), 1e-4);
          EXPECT_LT(rms.maxCoeff(), 1e-5);
        } else {
          // Projection methods are approximate on a 289-view grid that leaves the horizon unsampled. Worst texel
          // measured: sh-zh 0.144, sh-lsop 0.085 (the DC term is 0.56); bounds 1.5x those.
          EXPECT_LT(rms.maxCoeff(), kind == "sh-zh" ? 0.22 : 0.13);
        }
      }
  }
}

// Held-out views are left out of the fit (n drops) and holdout.R/G/B is the RMS on exactly them.
TEST(FitMap, HeldOutViewsGiveTheHoldoutRms) {
  const ObservationMap obs =
      make_map([](int s, int t, const Vec3d& d) { return texel_phong(s, t, false).evaluate(d); });
  const std::vector<int> held = {200, 3, 144};  // unsorted on purpose
  for (const std::string spec : {"phong:1", "hsh:3", "phong:auto"}) {
    SCOPED_TRACE(spec);
    MapFitOptions o = options_for(spec);
    o.held_out = held;
    auto map = fit_parameter_map(obs, o);
    ASSERT_TRUE(map) << map.error().describe();
    ASSERT_TRUE(map->has("holdout.R") && map->has("holdout.G") && map->has("holdout.B"));
    for (int t = 0; t < kT; ++t)
      for (int s = 0; s < kS; ++s) {
        EXPECT_EQ(map->at("n", s, t), 286.0f);
        const TexelObservations all = obs.texel(s, t);
        TexelObservations h;
        for (size_t i = 0; i < all.size(); ++i)
          if (all.view[i] == 3 || all.view[i] == 144 || all.view[i] == 200) {
            h.direction.push_back(all.direction[i]);
            h.radiance.push_back(all.radiance[i]);
            h.view.push_back(all.view[i]);
          }
        ASSERT_EQ(h.size(), 3u);
        const Vec3d rms = rms_by_evaluate(*map, s, t, h);
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(map->at(std::string("holdout.") + "RGB"[c], s, t), rms[c], 1e-5 + 1e-3 * rms[c]);
        // A 9-coefficient HSH cannot follow an m >= 40 lobe: its held-out error is real, Phong's is ~0.
        if (spec == "hsh:3") {
          EXPECT_GT(map->at("holdout.R", s, t) + map->at("holdout.G", s, t) + map->at("holdout.B", s, t), 1e-3);
        } else {
          EXPECT_LT(map->at("holdout.G", s, t), 1e-3);
        }
      }
  }
  MapFitOptions bad = options_for("phong:1");
  bad.held_out = {289};
  EXPECT_FALSE(fit_parameter_map(obs, bad));
}

// An SH map survives the file (OpenEXR stores channels sorted by name, not in the order they were added).
TEST(FitMap, ShMapRoundTripsThroughTheFile) {
  const ObservationMap obs =
      make_map([](int s, int t, const Vec3d& d) { return texel_phong(s, t, false).evaluate(d); });
  auto map = fit_parameter_map(obs, options_for("sh-ls:6"));
  ASSERT_TRUE(map) << map.error().describe();
  const test::TempDir dir("fit_map_sh");
  const auto path = dir / "map.exr";
  ASSERT_TRUE(map->write(path).is_ok());
  auto back = ParameterMap::read(path);
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_EQ(back->model().name(), "sh-ls:6");
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      EXPECT_EQ(harmonic_coefficients(*back, s, t), harmonic_coefficients(*map, s, t));
      const Vec3d v = Vec3d(0.1 * s - 0.2, 0.1 * t, 0.8).normalized();
      EXPECT_LT((back->evaluate(s, t, v) - map->evaluate(s, t, v)).norm(), 1e-9);
      EXPECT_GT(back->evaluate(s, t, v).minCoeff(), 0.0);
    }
}

// Fitting from an observation-map file, a tile at a time, gives exactly the in-memory fit (same float observations,
// same solver), for a model whose map is built at the end (phong:auto) and with held-out views; a damaged tile ends
// the fit with kCorrupt instead of a map with holes.
TEST(FitMap, FitFromFileTileByTileMatchesTheInMemoryFit) {
  const ObservationMap obs =
      make_map([](int s, int t, const Vec3d& d) { return texel_phong(s, t, (s + t) % 2 == 0).evaluate(d); });
  const test::TempDir dir("fit_map_file");
  const auto path = dir / "map.vdobs";
  ObsFileOptions file;
  file.tile_size = 2;  // 2 x 2 tiles over the 4 x 3 map, the last row of tiles partial
  ASSERT_TRUE(write_obsmap_file(obs, path, file).is_ok());
  auto reader = ObsMapReader::open(path);
  ASSERT_TRUE(reader) << reader.error().describe();
  for (const std::string spec : {"phong:1", "phong:auto", "hsh:4"}) {
    SCOPED_TRACE(spec);
    MapFitOptions o = options_for(spec);
    o.held_out = {3, 150};
    int progress_calls = 0, last_done = 0;
    o.on_progress = [&](const MapFitProgress& p) {
      ++progress_calls;
      last_done = p.texels_done;
    };
    auto from_file = fit_parameter_map(reader.value(), o);
    ASSERT_TRUE(from_file) << from_file.error().describe();
    EXPECT_EQ(progress_calls, 1);  // 12 texels: reported once, at the end
    EXPECT_EQ(last_done, kS * kT);
    o.on_progress = nullptr;
    auto in_memory = fit_parameter_map(obs, o);
    ASSERT_TRUE(in_memory);
    ASSERT_EQ(from_file->image().channel_names, in_memory->image().channel_names);
    EXPECT_EQ(from_file->model().name(), in_memory->model().name());
    for (size_t c = 0; c < in_memory->image().channel_names.size(); ++c) {
      const std::string& name = in_memory->image().channel_names[c];
      for (int t = 0; t < kT; ++t)
        for (int s = 0; s < kS; ++s) EXPECT_EQ(from_file->at(name, s, t), in_memory->at(name, s, t)) << name;
    }
    EXPECT_GT(from_file->at("holdout.G", 1, 1), 0.0f);
  }

  // Flip one byte inside the first tile's stored bytes (the tiles start after the 128-byte header).
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(200);
    char byte = 0;
    f.read(&byte, 1);
    byte = static_cast<char>(byte ^ 0x5A);
    f.seekp(200);
    f.write(&byte, 1);
  }
  auto damaged = ObsMapReader::open(path);
  ASSERT_TRUE(damaged) << "the header and index are intact: " << damaged.error().describe();
  auto fit = fit_parameter_map(damaged.value(), options_for("phong:1"));
  ASSERT_FALSE(fit);
  EXPECT_EQ(fit.error().code, ErrorCode::kCorrupt) << fit.error().describe();
}

TEST(FitMap, SparseTexelsGetZerosAndTheirCount) {
  ObservationMapSpec spec;
  spec.texels_s = 2;
  spec.texels_t = 1;
  ObservationMap obs(spec, 10);
  for (int v = 0; v < 3; ++v)
    obs.set(0, 0, v, Eigen::Vector3f(1, 1, 1), Eigen::Vector3f(0, 0, 1), kObsValid);  // only 3 < 6 observations
  auto map = fit_parameter_map(obs, options_for("sh-ls:2"));
  ASSERT_TRUE(map);
  EXPECT_EQ(map->at("n", 0, 0), 3.0f);
  EXPECT_EQ(map->at("n", 1, 0), 0.0f);
  EXPECT_EQ(map->evaluate(0, 0, Vec3d::UnitZ()), Vec3d::Zero());
}

}  // namespace
}  // namespace vdrig::fitting

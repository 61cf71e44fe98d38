// TiledMapFit (tiled_fit.hpp), in one process: tiles fitted in any order, records passed as bytes, the between-pass
// state installed in a second TiledMapFit (as another process would), give the map fit_parameter_map gives, bit for
// bit. The MPI driver on top is tested in tests/cluster.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/fitting/tiled_fit.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::fitting {
namespace {

constexpr int kTexels = 20;
constexpr double kSizeMm = 600.0;

/// Texels of one glossy Phong material lit by a point light at (300, 200, 1500) mm (each lobe at the light's mirror
/// direction), seen from a 9 x 9 grid of cameras 2000 mm away: the shared-lights fit has a light to find.
ObservationMap lit_map() {
  ObservationMapSpec spec{kTexels, kTexels, kSizeMm, kSizeMm};
  std::vector<Vec3d> cameras;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 9; ++j) {
      const double pan = deg_to_rad(-60.0 + 15.0 * i), tilt = deg_to_rad(-60.0 + 15.0 * j);
      cameras.push_back(2000.0 * Vec3d(std::cos(tilt) * std::sin(pan), std::sin(tilt), std::cos(tilt) * std::cos(pan)));
    }
  EstimatedLight light;
  light.position_mm = Vec3d(300, 200, 1500);
  ObservationMap map(spec, static_cast<int>(cameras.size()));
  for (int t = 0; t < kTexels; ++t)
    for (int s = 0; s < kTexels; ++s) {
      const Vec3d p = texel_centre_mm(s, t, kTexels, kTexels, kSizeMm, kSizeMm);
      PhongParams truth;
      truth.kd = Vec3d(0.2 + 0.01 * s, 0.15, 0.1 + 0.01 * t);
      PhongLobe lobe;
      lobe.ks = Vec3d(0.8, 0.7, 0.6);
      lobe.direction = mirror_direction_at(light, p);
      lobe.shininess = 40.0;
      truth.lobes = {lobe};
      for (size_t v = 0; v < cameras.size(); ++v) {
        const Vec3d d = (cameras[v] - p).normalized();
        map.set(s, t, static_cast<int>(v), truth.evaluate(d).cast<float>(), d.cast<float>(), kObsValid);
      }
    }
  return map;
}

void expect_bit_identical(const ParameterMap& a, const ParameterMap& b) {
  ASSERT_EQ(a.image().channel_names, b.image().channel_names);
  for (size_t c = 0; c < a.image().channels.size(); ++c) {
    const cv::Mat &pa = a.image().channels[c], &pb = b.image().channels[c];
    for (int y = 0; y < pa.rows; ++y)
      EXPECT_EQ(std::memcmp(pa.ptr<float>(y), pb.ptr<float>(y), sizeof(float) * pa.cols), 0)
          << a.image().channel_names[c] << " row " << y;
  }
  EXPECT_EQ(a.image().string_attributes, b.image().string_attributes);
  EXPECT_EQ(a.model().name(), b.model().name());
}

/// Every pass of every tile in a shuffled order; the refit pass in a second TiledMapFit given only the state.
ParameterMap fit_in_tiles(const ObsMapReader& reader, const MapFitOptions& options) {
  auto first = TiledMapFit::create(reader, options);
  EXPECT_TRUE(first) << first.error().describe();
  std::vector<std::vector<TileBytes>> records(static_cast<size_t>(first->passes()),
                                              std::vector<TileBytes>(static_cast<size_t>(first->tiles())));
  std::vector<int> order(static_cast<size_t>(first->tiles()));
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::mt19937 rng(7);
  std::shuffle(order.begin(), order.end(), rng);
  TiledMapFit* fit = &first.value();
  auto second = TiledMapFit::create(reader, options);
  for (int pass = 0; pass < first->passes(); ++pass) {
    for (int k : order) {
      auto r = fit->fit_tile(pass, k, pass ? &records[pass - 1][k] : nullptr);
      EXPECT_TRUE(r) << r.error().describe();
      records[pass][k] = r.value();
    }
    if (pass + 1 < first->passes()) {
      std::vector<TileBytes> summaries;
      for (int k = 0; k < first->tiles(); ++k) summaries.push_back(fit->summary(pass, k, records[pass][k]).value());
      auto state = fit->pass_state(pass, summaries);
      EXPECT_TRUE(state) << state.error().describe();
      fit = &second.value();
      EXPECT_TRUE(fit->set_pass_state(pass, state.value()));
    }
  }
  auto map = fit->assemble([&](int k) -> Result<TileBytes> { return records.back()[k]; });
  EXPECT_TRUE(map) << map.error().describe();
  return std::move(map.value());
}

class TiledFit : public ::testing::Test {
 protected:
  void SetUp() override {
    ObsFileOptions file;
    file.tile_size = 8;  // 3 x 3 tiles, the edge ones 4 texels wide
    ASSERT_TRUE(write_obsmap_file(lit_map(), dir_ / "lit.vdobs", file));
    auto reader = ObsMapReader::open(dir_ / "lit.vdobs");
    ASSERT_TRUE(reader) << reader.error().describe();
    reader_ = std::make_unique<ObsMapReader>(std::move(reader.value()));
  }
  test::TempDir dir_{"tiled_fit"};
  std::unique_ptr<ObsMapReader> reader_;
};

TEST_F(TiledFit, PhongAutoWithSharedLightsEqualsTheSingleProcessFit) {
  MapFitOptions options;
  options.model = parse_model("phong:auto").value();
  options.shared_lights = true;
  options.held_out = {3, 40};
  options.threads = 2;
  auto reference = fit_parameter_map(*reader_, options);
  ASSERT_TRUE(reference) << reference.error().describe();
  // The lights were found and used: the refit pass did something to compare.
  EXPECT_EQ(reference->image().string_attributes["vdrig.shared_lights"].rfind("point", 0), 0u);
  EXPECT_GT(cv::countNonZero(reference->image().channels[reference->image().find("shared_lights")]), 0);
  options.threads = 1;
  expect_bit_identical(reference.value(), fit_in_tiles(*reader_, options));
}

TEST_F(TiledFit, HshWithHeldOutViewsEqualsTheSingleProcessFit) {
  MapFitOptions options;
  options.model = parse_model("hsh:3").value();
  options.held_out = {5};
  auto reference = fit_parameter_map(*reader_, options);
  ASSERT_TRUE(reference) << reference.error().describe();
  expect_bit_identical(reference.value(), fit_in_tiles(*reader_, options));
}

TEST_F(TiledFit, RefusesWhatTheFitRefusesAndFingerprintsTheOptions) {
  MapFitOptions options;
  options.model = parse_model("hsh:3").value();
  options.shared_lights = true;
  auto refused = TiledMapFit::create(*reader_, options);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("Phong models only"), std::string::npos);
  options.shared_lights = false;
  MapFitOptions other = options;
  other.model_options.edit<HshFitOptions>().smoothing = 1e-4;
  EXPECT_NE(fit_options_fingerprint(options), fit_options_fingerprint(other));
  EXPECT_EQ(options.model_options.get<HshFitOptions>().smoothing, 0.0);  // the copy was edited, not the original
  other = options;
  other.model_options.edit<PhongFitOptions>().lobe_support = 5;  // an option hsh does not read
  EXPECT_EQ(fit_options_fingerprint(options), fit_options_fingerprint(other));
  other = options;
  other.threads = 7;  // not part of the result
  EXPECT_EQ(fit_options_fingerprint(options), fit_options_fingerprint(other));
}

}  // namespace
}  // namespace vdrig::fitting

// Issue #18: parameter maps are checked when loaded (finite values, the model's ranges, a size limit stated and
// applied from the header), and the map fit's thread count is validated with the other options.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/model.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::fitting {
namespace {
namespace fs = std::filesystem;

class MapChecks : public ::testing::Test {
 protected:
  /// A phong:1 map with every texel plausible, written to `name`, after `spoil` changed it.
  fs::path write_map(const std::string& name, const std::function<void(ParameterMap&)>& spoil) {
    auto model = parse_model("phong:1");
    EXPECT_TRUE(model);
    ParameterMap map(model.value(), 4, 3, 100.0, 80.0);
    for (int t = 0; t < 3; ++t)
      for (int s = 0; s < 4; ++s) map.at(shininess(map), s, t) = 20.0f;
    spoil(map);
    const fs::path p = dir_ / name;
    EXPECT_TRUE(map.write(p));
    return p;
  }
  static std::string shininess(const ParameterMap& map) { return map.has("m0") ? "m0" : "m"; }

  const test::TempDir dir_{"fitting_map_checks"};
};

TEST_F(MapChecks, PlausibleMapLoads) {
  auto ok = ParameterMap::read(write_map("ok.exr", [](ParameterMap&) {}));
  ASSERT_TRUE(ok) << ok.error().describe();
}

TEST_F(MapChecks, NonFiniteValuesAreRefused) {
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    auto r = ParameterMap::read(write_map("nan.exr", [bad](ParameterMap& m) { m.at("kd.G", 2, 1) = bad; }));
    ASSERT_FALSE(r) << bad;
    EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(r.error().message.find("kd.G"), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find("2,1"), std::string::npos) << r.error().message;
  }
}

TEST_F(MapChecks, NegativePhongExponentIsRefused) {
  auto r = ParameterMap::read(write_map("neg.exr", [](ParameterMap& m) { m.at(shininess(m), 1, 2) = -3.0f; }));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(r.error().message.find("negative"), std::string::npos) << r.error().message;
}

TEST_F(MapChecks, OversizedMapIsRefusedFromItsHeaderBeforeAllocating) {
  // A 1 x 1 map whose header is patched to claim 99999 x 99999 texels: refused from the header (before, the
  // reader allocated every channel at that size).
  auto model = parse_model("phong:1");
  ASSERT_TRUE(model);
  ParameterMap small(model.value(), 1, 1, 10.0, 10.0);
  const fs::path p = dir_ / "huge.exr";
  ASSERT_TRUE(small.write(p));
  std::ifstream in(p, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  const std::string key = std::string("dataWindow") + '\0' + "box2i" + '\0';
  const size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos);
  const int32_t window[4] = {0, 0, 99998, 99998};  // xmin ymin xmax ymax, little-endian on every vdrig target
  bytes.replace(at + key.size() + 4, 16, reinterpret_cast<const char*>(window), 16);
  // Room for the line-offset table such a header announces (99999 lines in 16-line chunks), so that the header
  // itself reads back and only the size can stop the reader.
  bytes.append(100000, '\0');
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
  auto r = ParameterMap::read(p);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument) << r.error().describe();
  EXPECT_NE(r.error().message.find("MiB"), std::string::npos) << r.error().message;
}

TEST(MapFitOptions, ThreadCountIsValidated) {
  ObservationMap obs(ObservationMapSpec{2, 2, 10.0, 10.0}, 1);
  MapFitOptions options;
  auto model = parse_model("phong:1");
  ASSERT_TRUE(model);
  options.model = model.value();
  options.threads = 100000;  // used to start 100000 workers (2.6 GB, then an abort)
  auto r = fit_parameter_map(obs, options);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message.find("threads"), std::string::npos) << r.error().message;
  options.threads = -1;
  EXPECT_FALSE(fit_parameter_map(obs, options));
}

}  // namespace
}  // namespace vdrig::fitting

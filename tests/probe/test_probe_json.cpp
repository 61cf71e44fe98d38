// The JSON files of `vdrig probe lights` and `vdrig probe irradiance`: what is written reads back exactly, and a
// malformed file is a kCorrupt value naming what is wrong, never an exception.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "probe_support.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/probe/probe_json.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::probe {
namespace {

using testing::synthetic_probe;

// A map with colour and direction structure, so that swapped channels or axes show.
Probe structured_probe() {
  return synthetic_probe(32, [](const Vec3d& d) {
    return Rgb(1.0 + 0.9 * d.x(), 0.5 + 0.4 * d.z() * d.z(), 0.2 + 0.1 * d.y() + (d.z() > 0.9 ? 30.0 : 0.0));
  });
}

TEST(ProbeJson, LightsRoundTripExactly) {
  const Probe p = structured_probe();
  const LightsDocument doc{"dir/room.exr", median_cut(p, 16)};
  ASSERT_EQ(doc.lights.size(), 16u);
  const std::string text = lights_to_json(doc);
  auto back = lights_from_json(text);
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_EQ(back->source, "dir/room.exr");
  ASSERT_EQ(back->lights.size(), doc.lights.size());
  for (size_t k = 0; k < doc.lights.size(); ++k) {
    EXPECT_EQ(back->lights[k].direction, doc.lights[k].direction) << k;
    EXPECT_EQ(back->lights[k].power, doc.lights[k].power) << k;
    EXPECT_EQ(back->lights[k].solid_angle_sr, doc.lights[k].solid_angle_sr) << k;
    // Written as a half-angle in degrees (the edge's unit), so exact to a rounding of the conversion.
    EXPECT_LT(doc.lights[k].cap_cos_half_angle, 1.0) << k;
    EXPECT_NEAR(back->lights[k].cap_cos_half_angle, doc.lights[k].cap_cos_half_angle, 1e-14) << k;
  }
  // The angles written for reading by eye describe the same direction (azimuth from +x toward +y).
  const auto j = nlohmann::json::parse(text);
  EXPECT_EQ(j.at("format"), "vdrig.probe.lights");
  EXPECT_EQ(j.at("version"), kLightsFormatVersion);
  for (size_t k = 0; k < doc.lights.size(); ++k) {
    const auto& e = j.at("lights").at(k);
    const Vec3d d = direction_from_spherical(deg_to_rad(e.at("azimuth_deg").get<double>()),
                                             deg_to_rad(e.at("zenith_deg").get<double>()));
    EXPECT_LT((d - doc.lights[k].direction).norm(), 1e-12) << k;
  }
}

TEST(ProbeJson, Sh9RoundTripsExactly) {
  const Probe p = structured_probe();
  const Sh9Document doc{"room.exr", project_sh9(p)};
  auto back = sh9_from_json(sh9_to_json(doc));
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_EQ(back->source, "room.exr");
  for (int i = 0; i < kSh9Count; ++i) EXPECT_EQ(back->radiance.coeffs[i], doc.radiance.coeffs[i]) << i;
  const auto j = nlohmann::json::parse(sh9_to_json(doc));
  EXPECT_EQ(j.at("format"), "vdrig.probe.sh9");
  for (int l = 0; l < 3; ++l) EXPECT_EQ(j.at("cosine_factors").at(l).get<double>(), sh9_cosine_factor(l));
}

// Every malformed input gives kCorrupt whose message contains `names`.
void expect_corrupt(const std::string& text, const std::string& names, bool lights) {
  Status s;
  EXPECT_NO_THROW(s = lights ? lights_from_json(text).status() : sh9_from_json(text).status()) << text;
  ASSERT_FALSE(s) << text;
  EXPECT_EQ(s.error().code, ErrorCode::kCorrupt) << text;
  EXPECT_NE(s.error().message.find(names), std::string::npos) << "'" << s.error().message << "' for " << text;
}

TEST(ProbeJson, MalformedLightsAreErrorsNamingTheProblem) {
  const std::string head = R"({"format": "vdrig.probe.lights", "version": 1, )";
  const std::string ok_light = R"({"direction": [0, 0, 1], "power": [1, 2, 3], "solid_angle_sr": 0.5})";
  ASSERT_TRUE(lights_from_json(head + R"("lights": [)" + ok_light + "]}")) << "the base case must parse";
  expect_corrupt("", "invalid JSON", true);
  expect_corrupt(R"({"format": "vdrig.probe.lights", "version": 1, "lights": [)", "invalid JSON", true);
  expect_corrupt("[1, 2]", "not a JSON object", true);
  expect_corrupt(R"({"format": "vdrig.probe.sh9", "version": 1, "lights": []})", "\"format\"", true);
  expect_corrupt(R"({"version": 1, "lights": []})", "\"format\"", true);
  expect_corrupt(R"({"format": "vdrig.probe.lights", "version": 2, "lights": []})", "\"version\"", true);
  expect_corrupt(R"({"format": "vdrig.probe.lights", "version": "1", "lights": []})", "\"version\"", true);
  expect_corrupt(head + R"("lights": {}})", "\"lights\"", true);
  expect_corrupt(R"({"format": "vdrig.probe.lights", "version": 1})", "\"lights\"", true);
  expect_corrupt(head + R"("lights": [1]})", "light 0", true);
  expect_corrupt(head + R"("lights": [)" + ok_light + R"(, {"power": [1, 2, 3], "solid_angle_sr": 1}]})",
                 "light 1: missing \"direction\"", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 1], "power": [1, 2, 3], "solid_angle_sr": 1}]})",
                 "\"direction\" must be an array of 3", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 0, 2], "power": [1, 2, 3], "solid_angle_sr": 1}]})",
                 "not a unit vector", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 0, 1], "power": [1, "2", 3], "solid_angle_sr": 1}]})",
                 "\"power\" must be an array of 3 finite numbers", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 0, 1], "power": [1, -2, 3], "solid_angle_sr": 1}]})",
                 "\"power\" must be >= 0", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 0, 1], "power": [1, 2, 3]}]})", "\"solid_angle_sr\"", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 0, 1], "power": [1, 2, 3], "solid_angle_sr": -1}]})",
                 "\"solid_angle_sr\"", true);
  expect_corrupt(head + R"("lights": [{"direction": [0, 0, 1], "power": [1, 2, 3], "solid_angle_sr": 1, )"
                        R"("cap_half_angle_deg": 90}]})",
                 "\"cap_half_angle_deg\" must be a number in [0, 90)", true);
}

TEST(ProbeJson, MalformedSh9IsAnErrorNamingTheProblem) {
  std::string coeffs;
  for (int i = 0; i < kSh9Count; ++i) coeffs += std::string(i ? ", " : "") + "[0.1, 0.2, 0.3]";
  const std::string head = R"({"format": "vdrig.probe.sh9", "version": 1, )";
  ASSERT_TRUE(sh9_from_json(head + R"("radiance_coefficients": [)" + coeffs + "]}")) << "the base case must parse";
  expect_corrupt("not json", "invalid JSON", false);
  expect_corrupt(R"({"format": "vdrig.probe.lights", "version": 1})", "\"format\"", false);
  expect_corrupt(R"({"format": "vdrig.probe.sh9", "version": 7})", "\"version\"", false);
  expect_corrupt(head + R"("radiance_coefficients": [[1, 2, 3]]})", "\"radiance_coefficients\"", false);
  expect_corrupt(R"({"format": "vdrig.probe.sh9", "version": 1})", "\"radiance_coefficients\"", false);
  expect_corrupt(head + R"("radiance_coefficients": [)" + coeffs + R"(, [1, 2, 3]]})", "\"radiance_coefficients\"",
                 false);
  std::string bad = coeffs;
  bad.replace(bad.rfind("0.3"), 3, "null");
  expect_corrupt(head + R"("radiance_coefficients": [)" + bad + "]}", "radiance coefficient 8", false);
}

TEST(ProbeJson, RoomRoundTripsAndMalformedRoomsNameTheProblem) {
  RoomDocument room;
  room.room = ProxyBox{Vec3d(-2000, -1500, 0), Vec3d(2000, 1500, 2600)};
  room.probes = {{"a.exr", true, Vec3d(-1000, -700, 1200.5)}, {"sub/b.exr", false, Vec3d::Zero()}};
  auto back = room_from_json(room_to_json(room));
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_EQ(back->room.min_mm, room.room.min_mm);
  EXPECT_EQ(back->room.max_mm, room.room.max_mm);
  ASSERT_EQ(back->probes.size(), 2u);
  EXPECT_EQ(back->probes[0].file, "a.exr");
  EXPECT_TRUE(back->probes[0].has_position);
  EXPECT_EQ(back->probes[0].position_mm, room.probes[0].position_mm);
  EXPECT_EQ(back->probes[1].file, "sub/b.exr");
  EXPECT_FALSE(back->probes[1].has_position);

  auto expect = [](const std::string& text, const std::string& what) {
    auto r = room_from_json(text);
    ASSERT_FALSE(r) << text;
    EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(r.error().message.find(what), std::string::npos) << r.error().message;
  };
  const std::string head = R"({"format": "vdrig.probe.room", "version": 1, )";
  const std::string box = R"("room_mm": {"min": [0, 0, 0], "max": [1, 1, 1]}, )";
  expect("{", "not valid JSON");
  expect(R"({"format": "vdrig.probe.path", "version": 1})", "\"format\"");
  expect(R"({"format": "vdrig.probe.room", "version": 2})", "\"version\"");
  expect(head + R"("probes": [{"file": "a.exr"}]})", "\"room_mm\"");
  expect(head + R"("room_mm": {"min": [0, 0, 0], "max": [1, 1]}, "probes": [{"file": "a.exr"}]})", "\"max\"");
  expect(head + R"("room_mm": {"min": [0, 0, 0], "max": [1, -1, 1]}, "probes": [{"file": "a.exr"}]})", "min < max");
  expect(head + box + R"("probes": []})", "non-empty");
  expect(head + box + R"("probes": [{"position_mm": [0, 0, 0]}]})", "probe 0 needs a \"file\"");
  expect(head + box + R"("probes": [{"file": "a.exr", "position_mm": [0, 0]}]})", "\"position_mm\"");
  // get<int> wrapped 2^32 + 1 to 1, so this room was read as version 1 (found with fuzz/fuzz_probe_room's check).
  expect(R"({"format": "vdrig.probe.room", "version": 4294967297, )" + box + R"("probes": [{"file": "a.exr"}]})",
         "\"version\"");
}

TEST(ProbeJson, FuzzProbeRoomRegressionsParseToAValueOrAnError) {
  const std::filesystem::path folder = std::filesystem::path(VDRIG_SOURCE_DIR) / "fuzz" / "regressions" / "probe_room";
  if (!std::filesystem::is_directory(folder)) GTEST_SKIP() << "no " << folder;
  int replayed = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const auto text = read_regular_file(entry.path(), 1 << 20);
    ASSERT_TRUE(text) << text.error().describe();
    Result<RoomDocument> room = RoomDocument{};
    ASSERT_NO_THROW(room = room_from_json(*text)) << entry.path();
    // Each kept input is one the parser wrongly accepted or crashed on: all are errors now.
    EXPECT_FALSE(room) << entry.path();
    ++replayed;
  }
  EXPECT_GT(replayed, 0);
}

}  // namespace
}  // namespace vdrig::probe

// Bad input gives a clear error, not an abort: a probe of the wrong aspect, NaN pixels, the panorama layout written
// back, and an object path that is empty, malformed or leaves the room (object_path.hpp), including what
// fuzz/fuzz_probe_path found (its inputs kept in fuzz/regressions/probe_path/ are replayed here).
#include <gtest/gtest.h>

#include <filesystem>
#include <limits>

#include "probe_support.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/probe/object_path.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::probe {
namespace {

using testing::synthetic_probe;

ExrImage rgb_planes(int width, int height) {
  ExrImage im;
  for (const char* c : {"R", "G", "B"}) im.add(c, cv::Mat(height, width, CV_32FC1, cv::Scalar(0.5)));
  return im;
}

void expect_error(const Status& s, ErrorCode code, const std::string& part) {
  ASSERT_FALSE(s.is_ok()) << "expected an error mentioning '" << part << "'";
  EXPECT_EQ(s.error().code, code) << s.error().describe();
  EXPECT_NE(s.error().message.find(part), std::string::npos) << s.error().message;
}

TEST(BadInput, ProbeOfTheWrongAspectIsRejected) {
  const test::TempDir dir("probe_bad");
  for (const auto& [w, h] : {std::pair{64, 64}, std::pair{96, 64}, std::pair{66, 32}}) {
    ASSERT_TRUE(write_exr(dir / "wrong.exr", rgb_planes(w, h)).is_ok());
    auto p = load_probe(dir / "wrong.exr");
    ASSERT_FALSE(p);
    expect_error(p.error(), ErrorCode::kInvalidArgument, "not a 2:1 latitude-longitude map");
    EXPECT_NE(p.error().message.find(std::to_string(w) + " x " + std::to_string(h)), std::string::npos);
  }
}

TEST(BadInput, NanPixelsAreNamed) {
  const test::TempDir dir("probe_bad");
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    ExrImage im = rgb_planes(32, 16);
    im.channels[2].at<float>(5, 7) = bad;
    ASSERT_TRUE(write_exr(dir / "nan.exr", im).is_ok());
    LoadOptions o;
    o.azimuth = FileAzimuth::kDesignNotes;
    auto p = load_probe(dir / "nan.exr", o);
    ASSERT_FALSE(p);
    expect_error(p.error(), ErrorCode::kCorrupt, "non-finite value at (7, 5)");
  }
}

TEST(BadInput, PanoramaLayoutWrittenBackLiesOverTheSource) {
  // save_probe(kPanorama) is load_probe's inverse: the file matches the source column for column.
  const test::TempDir dir("probe_bad");
  ExrImage src = rgb_planes(32, 16);
  for (int c = 0; c < 32; ++c) src.channels[0].col(c).setTo(cv::Scalar(c));
  ASSERT_TRUE(write_exr(dir / "pano.exr", src).is_ok());
  FileAzimuth layout = FileAzimuth::kDesignNotes;
  auto p = load_probe(dir / "pano.exr", {}, &layout);
  ASSERT_TRUE(p);
  EXPECT_EQ(layout, FileAzimuth::kPanorama);
  ASSERT_TRUE(save_probe(dir / "back.exr", *p, FileAzimuth::kPanorama).is_ok());
  auto back = read_exr(dir / "back.exr");
  ASSERT_TRUE(back);
  EXPECT_EQ(cv::norm(back->channels[back->find("R")], src.channels[0], cv::NORM_INF), 0);
  auto ours = load_probe(dir / "back.exr");
  ASSERT_TRUE(ours);
  EXPECT_EQ(cv::norm(ours->radiance, p->radiance, cv::NORM_INF), 0);
  ASSERT_TRUE(save_probe(dir / "ours.exr", *p).is_ok());
  ASSERT_TRUE(load_probe(dir / "ours.exr", {}, &layout));
  EXPECT_EQ(layout, FileAzimuth::kDesignNotes);
}

const ProxyBox kRoom{Vec3d(-2000, -1500, 0), Vec3d(2000, 1500, 2600)};

TEST(BadInput, EmptyPathIsRejected) {
  expect_error(validate_path({}, kRoom), ErrorCode::kInvalidArgument, "path is empty");
  auto parsed = path_from_json(R"({"format": "vdrig.probe.path", "version": 1, "keys": []})");
  ASSERT_TRUE(parsed);
  expect_error(validate_path(*parsed, kRoom), ErrorCode::kInvalidArgument, "path is empty");
}

TEST(BadInput, PathLeavingTheRoomIsRejectedNamingKeyAndWall) {
  ObjectPath path;
  path.keys = {{0, Vec3d(0, 0, 1000)}, {1, Vec3d(1000, 0, 1000)}, {2, Vec3d(2100, 0, 1000)}};
  expect_error(validate_path(path, kRoom), ErrorCode::kInvalidArgument, "path key 2");
  expect_error(validate_path(path, kRoom), ErrorCode::kInvalidArgument, "x max wall");
  path.keys[2].position_mm = Vec3d(1000, 0, -5);
  expect_error(validate_path(path, kRoom), ErrorCode::kInvalidArgument, "z min wall");
  path.keys[2].position_mm = Vec3d(1950, 0, 1000);
  EXPECT_TRUE(validate_path(path, kRoom).is_ok());
  expect_error(validate_path(path, kRoom, 100), ErrorCode::kInvalidArgument, "x max wall");  // the object's radius
  path.keys[2].time_s = 1;
  expect_error(validate_path(path, kRoom), ErrorCode::kInvalidArgument, "times must increase");
  path.keys[2] = {2, Vec3d(0, std::numeric_limits<double>::quiet_NaN(), 0)};
  expect_error(validate_path(path, kRoom), ErrorCode::kInvalidArgument, "non-finite");
}

TEST(BadInput, PathJsonRoundTripsAndMalformedJsonIsCorrupt) {
  ObjectPath path;
  path.keys = {{0, Vec3d(0, 0, 1000)}, {2, Vec3d(1000, 500, 1200)}};
  auto back = path_from_json(path_to_json(path));
  ASSERT_TRUE(back);
  ASSERT_EQ(back->keys.size(), 2u);
  EXPECT_EQ(back->keys[1].position_mm, path.keys[1].position_mm);
  EXPECT_EQ(position_at(*back, 1.0), Vec3d(500, 250, 1100));
  EXPECT_EQ(position_at(*back, -1.0), path.keys[0].position_mm);
  const auto frames = sample_path(*back, 5);
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(frames.back(), path.keys[1].position_mm);
  for (const char* bad : {"", "{", R"({"format": "x", "version": 1, "keys": []})",
                          R"({"format": "vdrig.probe.path", "version": 2, "keys": []})",
                          R"({"format": "vdrig.probe.path", "version": 1, "keys": [{"time_s": 0}]})"}) {
    auto p = path_from_json(bad);
    ASSERT_FALSE(p) << bad;
    EXPECT_EQ(p.error().code, ErrorCode::kCorrupt) << bad;
  }
}

TEST(BadInput, PathJsonWithAMistypedFormatOrAWrappingVersionIsCorrupt) {
  // json::value("format", "") threw type_error on these (found by fuzz_probe_path: an uncaught exception).
  for (const char* bad : {R"({"format": {}})", R"({"format": 1, "version": 1, "keys": []})"}) {
    Result<ObjectPath> p = ObjectPath{};
    ASSERT_NO_THROW(p = path_from_json(bad)) << bad;
    ASSERT_FALSE(p) << bad;
    EXPECT_EQ(p.error().code, ErrorCode::kCorrupt) << bad;
    EXPECT_NE(p.error().message.find("\"format\""), std::string::npos) << p.error().message;
  }
  // get<int> wrapped 2^32 + 1 to 1, so this was read as version 1.
  auto p = path_from_json(R"({"format": "vdrig.probe.path", "version": 4294967297, "keys": []})");
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find("\"version\""), std::string::npos) << p.error().message;
}

TEST(BadInput, PathWhoseDurationOverflowsIsRejected) {
  // -1e308 .. 1e308 s: the duration is inf, and sample_path's first frame was NaN (inf * 0).
  ObjectPath path;
  path.keys = {{-1e308, Vec3d(0, 0, 1000)}, {1e308, Vec3d(10, 0, 1000)}};
  expect_error(validate_path(path, kRoom), ErrorCode::kInvalidArgument, "duration must be a finite");
  path.keys[1].time_s = 7e307;  // a span of 1.7e308 s still fits a double
  EXPECT_TRUE(validate_path(path, kRoom).is_ok());
  for (const Vec3d& p : sample_path(path, 5)) EXPECT_TRUE(kRoom.contains(p)) << p.transpose();
}

TEST(BadInput, LastSampledFrameIsTheLastKeyExactly) {
  // t0 + (t1 - t0) * 6 / 6 rounds to 16.529999999999998 < 16.53 (an independent check in plain doubles), so the
  // last of 7 frames was interpolated just short of the last key.
  const double t0 = 0.8, t1 = 16.53;
  ASSERT_LT(t0 + (t1 - t0) * 6 / 6, t1);
  ObjectPath path;
  path.keys = {{t0, Vec3d(0, 0, 1000)}, {t1, Vec3d(10, 20, 1000)}};
  ASSERT_TRUE(validate_path(path, kRoom).is_ok());
  const auto frames = sample_path(path, 7);
  EXPECT_EQ(frames.front(), path.keys.front().position_mm);
  EXPECT_EQ(frames.back(), path.keys.back().position_mm);
}

TEST(BadInput, FuzzProbePathRegressionsParseToAValueOrAnError) {
  const std::filesystem::path folder = std::filesystem::path(VDRIG_SOURCE_DIR) / "fuzz" / "regressions" / "probe_path";
  if (!std::filesystem::is_directory(folder)) GTEST_SKIP() << "no " << folder;
  int replayed = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const auto text = read_regular_file(entry.path(), 1 << 20);
    ASSERT_TRUE(text) << text.error().describe();
    Result<ObjectPath> path = ObjectPath{};
    ASSERT_NO_THROW(path = path_from_json(*text)) << entry.path();
    ++replayed;
    if (!path || !validate_path(*path, kRoom, 100)) continue;
    // What fuzz_probe_path checks of a path the app would use.
    const auto frames = sample_path(*path, 7);
    EXPECT_EQ(frames.front(), path->keys.front().position_mm) << entry.path();
    EXPECT_EQ(frames.back(), path->keys.back().position_mm) << entry.path();
    for (const Vec3d& p : frames) EXPECT_TRUE(kRoom.contains(p)) << entry.path() << ": " << p.transpose();
  }
  EXPECT_GT(replayed, 0);
}

}  // namespace
}  // namespace vdrig::probe

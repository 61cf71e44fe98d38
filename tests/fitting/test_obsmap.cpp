// Observation-map file (obsmap_file.hpp): the streaming writer vs the in-memory map built from the same synthetic
// views, the file's error handling (truncated, corrupt, wrong magic/version, out-of-range tiles, full disk) and its
// atomic publication.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::fitting {
namespace {
namespace fs = std::filesystem;

/// A 20 x 13 map (edge tiles are partial with 8-texel tiles) over a 1000 x 800 mm surface, seen by 11 views spread
/// over the hemisphere (one beyond the horizon, one excluded, one with a clip mask), through a small distorted
/// camera that does not see the whole surface from every view.
struct Fixture {
  ObservationMapSpec spec{20, 13, 1000.0, 800.0};
  std::vector<ViewInput> views;

  Fixture() {
    const CameraModel cam{160, 120, 380.0, 380.0, 79.5, 59.5, -0.05, 0.01, 0.0, 0.0, 0.0};
    const rig::RigGeometry geometry{2500.0, Vec3d(30.0, -20.0, 0.0)};
    const double pans_deg[] = {0, 30, 75, 120, 165, 210, 255, 300, 345, 45, 90};
    const double tilts_deg[] = {0, 20, 35, 50, 65, 40, 25, 55, 70, 100, 30};
    for (int v = 0; v < 11; ++v) {
      ViewInput in;
      in.camera = cam;
      in.pose = rig::surface_pose(geometry, PanTilt{deg_to_rad(pans_deg[v]), deg_to_rad(tilts_deg[v])});
      in.radiance_bgr.create(cam.height, cam.width, CV_32FC3);
      for (int y = 0; y < cam.height; ++y)
        for (int x = 0; x < cam.width; ++x)
          in.radiance_bgr.at<cv::Vec3f>(y, x) = cv::Vec3f(0.1f + 0.01f * v, 0.2f + 0.003f * y, 0.3f + 0.002f * x);
      if (v == 3) {
        in.clip_mask = cv::Mat::zeros(cam.height, cam.width, CV_8UC1);
        in.clip_mask(cv::Rect(60, 40, 40, 40)).setTo(255);
      }
      in.excluded = v == 5;
      views.push_back(std::move(in));
    }
  }

  ObservationMap in_memory() const {
    ObservationMap map(spec, static_cast<int>(views.size()));
    for (size_t v = 0; v < views.size(); ++v) add_view(map, static_cast<int>(v), views[v]);
    return map;
  }

  /// Streams the views into `path` in a shuffled order (the writer accepts any order).
  Status write(const fs::path& path, const ObsFileOptions& opt) const {
    auto w = ObsMapWriter::create(path, spec, static_cast<int>(views.size()), opt);
    if (!w) return w.error();
    std::vector<int> order(views.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::shuffle(order.begin(), order.end(), std::mt19937(7));
    for (int v : order) VDRIG_TRY(w->add_view(v, views[v]));
    return w->finish();
  }
};

ObsFileOptions options(ObsCompression c, int tile = 8) {
  ObsFileOptions o;
  o.compression = c;
  o.tile_size = tile;
  return o;
}

/// Every observation of the file equals the in-memory map's, bit for bit, read tile by tile.
void expect_identical(const ObservationMap& mem, const ObsMapReader& file) {
  ASSERT_EQ(file.views(), mem.views());
  ASSERT_EQ(file.spec().texels_s, mem.spec().texels_s);
  ASSERT_EQ(file.spec().texels_t, mem.spec().texels_t);
  EXPECT_EQ(file.spec().width_mm, mem.spec().width_mm);
  EXPECT_EQ(file.spec().height_mm, mem.spec().height_mm);
  int compared = 0;
  for (int tt = 0; tt < file.tiles_t(); ++tt)
    for (int ts = 0; ts < file.tiles_s(); ++ts) {
      auto tile = file.read_tile(ts, tt);
      ASSERT_TRUE(tile) << tile.error().describe();
      for (int t = tile->t0(); t < tile->t0() + tile->height(); ++t)
        for (int s = tile->s0(); s < tile->s0() + tile->width(); ++s) {
          for (int v = 0; v < mem.views(); ++v) {
            Eigen::Vector3f a_rgb, a_dir, b_rgb, b_dir;
            const uint8_t fa = mem.observation(s, t, v, &a_rgb, &a_dir);
            const uint8_t fb = tile->observation(s, t, v, &b_rgb, &b_dir);
            ASSERT_EQ(fa, fb) << "texel " << s << "," << t << " view " << v;
            ASSERT_EQ(a_rgb, b_rgb) << "texel " << s << "," << t << " view " << v;
            ASSERT_EQ(a_dir, b_dir) << "texel " << s << "," << t << " view " << v;
            ++compared;
          }
          const std::vector<int> held_out = {1, 4};
          const TexelObservations a = mem.texel(s, t, held_out), b = tile->texel(s, t, held_out);
          ASSERT_EQ(a.view, b.view);
          ASSERT_EQ(a.radiance, b.radiance);
          ASSERT_EQ(a.direction, b.direction);
        }
    }
  EXPECT_EQ(compared, mem.spec().texels_s * mem.spec().texels_t * mem.views());
}

TEST(ObsMapFile, InMemoryMapFromSyntheticViewsHasEveryKindOfObservation) {
  // Guards the round-trip tests: they only mean something if the views give valid and each kind of invalid one.
  const Fixture f;
  const ObservationMap mem = f.in_memory();
  int count[32] = {};
  for (int t = 0; t < f.spec.texels_t; ++t)
    for (int s = 0; s < f.spec.texels_s; ++s)
      for (int v = 0; v < mem.views(); ++v) {
        Eigen::Vector3f rgb, dir;
        const uint8_t flag = mem.observation(s, t, v, &rgb, &dir);
        ++count[flag];
        if (flag == kObsValid) {
          // Direction toward the camera centre, as the pose says (ground truth in double precision).
          const Vec3d p = texel_centre_mm(s, t, f.spec.texels_s, f.spec.texels_t, f.spec.width_mm, f.spec.height_mm);
          const Vec3d truth = f.views[v].pose.view_direction(p);
          EXPECT_LT((dir.cast<double>() - truth).norm(), 1e-6);
          EXPECT_NEAR(rgb.x(), 0.3 + 0.002 * f.views[v].camera.project(f.views[v].pose.to_camera(p)).x(), 1e-4);
        }
      }
  const int total = f.spec.texels_s * f.spec.texels_t * mem.views();
  EXPECT_GT(count[kObsValid], total / 3);
  EXPECT_GT(count[kObsOutside], 0);
  EXPECT_EQ(count[kObsBackFacing], f.spec.texels_s * f.spec.texels_t);  // the tilt-100 view, all of it
  EXPECT_EQ(count[kObsExcluded], f.spec.texels_s * f.spec.texels_t);
  EXPECT_GT(count[kObsClipped], 0);
}

TEST(ObsMapFile, StreamedFileMatchesInMemoryMapUncompressed) {
  const Fixture f;
  const test::TempDir dir("obsmap_raw");
  const fs::path path = dir / "map.vdobs";
  const Status st = f.write(path, options(ObsCompression::kNone));
  ASSERT_TRUE(st) << st.describe();
  auto reader = ObsMapReader::open(path);
  ASSERT_TRUE(reader) << reader.error().describe();
  EXPECT_EQ(reader->header().compression, ObsCompression::kNone);
  EXPECT_EQ(reader->tiles_s(), 3);
  EXPECT_EQ(reader->tiles_t(), 2);
  const uint64_t raw = 25ull * f.spec.texels_s * f.spec.texels_t * f.views.size();
  EXPECT_EQ(reader->header().raw_tile_bytes, raw);
  EXPECT_EQ(reader->header().stored_tile_bytes, raw);
  EXPECT_EQ(fs::file_size(path), 128 + raw + 24 * 6);
  expect_identical(f.in_memory(), reader.value());
  // Only the result is left in the folder: no temporary or spill file.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(ObsMapFile, StreamedFileMatchesInMemoryMapCompressed) {
  const Fixture f;
  const test::TempDir dir("obsmap_zstd");
  for (const int tile : {8, 32, 1}) {
    const fs::path path = dir / ("map" + std::to_string(tile) + ".vdobs");
    const Status st = f.write(path, options(ObsCompression::kZstd, tile));
    ASSERT_TRUE(st) << st.describe();
    auto reader = ObsMapReader::open(path);
    ASSERT_TRUE(reader) << reader.error().describe();
    EXPECT_EQ(reader->header().compression, ObsCompression::kZstd);
    EXPECT_EQ(reader->header().tile_size, tile);
    if (tile >= 8) {
      EXPECT_LT(reader->header().stored_tile_bytes, reader->header().raw_tile_bytes);
    }
    expect_identical(f.in_memory(), reader.value());
    auto all = reader->read_all();
    ASSERT_TRUE(all) << all.error().describe();
    EXPECT_EQ(all->texel(7, 9).radiance, f.in_memory().texel(7, 9).radiance);
  }
}

TEST(ObsMapFile, InMemoryMapWrittenToFileReadsBack) {
  const Fixture f;
  const test::TempDir dir("obsmap_from_map");
  const ObservationMap mem = f.in_memory();
  ASSERT_TRUE(write_obsmap_file(mem, dir / "m.vdobs"));
  auto reader = ObsMapReader::open(dir / "m.vdobs");
  ASSERT_TRUE(reader) << reader.error().describe();
  expect_identical(mem, reader.value());
}

std::vector<char> slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
void spit(const fs::path& p, const std::vector<char>& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

TEST(ObsMapFile, TruncatedAndCorruptFilesAreRejectedWithTheReason) {
  const Fixture f;
  const test::TempDir dir("obsmap_corrupt");
  const fs::path good = dir / "good.vdobs", bad = dir / "bad.vdobs";
  for (const auto c : {ObsCompression::kNone, ObsCompression::kZstd}) {
    ASSERT_TRUE(f.write(good, options(c)));
    const std::vector<char> bytes = slurp(good);
    ASSERT_TRUE(ObsMapReader::open(good));

    // Truncated anywhere: in the header, in the tiles, in the index.
    for (const size_t len : {size_t{0}, size_t{50}, size_t{127}, bytes.size() / 2, bytes.size() - 1}) {
      spit(bad, std::vector<char>(bytes.begin(), bytes.begin() + static_cast<long>(len)));
      auto r = ObsMapReader::open(bad);
      ASSERT_FALSE(r) << "length " << len;
      EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
      EXPECT_NE(r.error().message.find("truncated"), std::string::npos) << r.error().message;
    }
    // Wrong magic.
    std::vector<char> b = bytes;
    b[0] = 'X';
    spit(bad, b);
    auto r = ObsMapReader::open(bad);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(r.error().message.find("magic"), std::string::npos) << r.error().message;
    // A newer format version.
    b = bytes;
    b[8] = 3;
    spit(bad, b);
    r = ObsMapReader::open(bad);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code, ErrorCode::kUnsupported);
    EXPECT_NE(r.error().message.find("version 3"), std::string::npos) << r.error().message;
    // A version-1 file (before grazing samples were flagged; the same layout) is still read, as written.
    ASSERT_EQ(static_cast<unsigned char>(bytes[8]), kObsFileVersion);
    b = bytes;
    b[8] = 1;
    const uint64_t checksum = obsfile_hash64(b.data(), 120);
    std::memcpy(b.data() + 120, &checksum, sizeof checksum);
    spit(bad, b);
    r = ObsMapReader::open(bad);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->header().version, 1u);
    EXPECT_EQ(r->views(), static_cast<int>(f.views.size()));
    // A damaged header field (texels_s).
    b = bytes;
    b[16] ^= 0x04;
    spit(bad, b);
    r = ObsMapReader::open(bad);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(r.error().message.find("header checksum"), std::string::npos) << r.error().message;
    // A damaged index entry.
    b = bytes;
    b[b.size() - 30] ^= 0x10;
    spit(bad, b);
    r = ObsMapReader::open(bad);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(r.error().message.find("index"), std::string::npos) << r.error().message;
    // One flipped bit in the first tile's data: the file opens, that tile is rejected, the others still read.
    b = bytes;
    b[128 + 40] ^= 0x01;
    spit(bad, b);
    r = ObsMapReader::open(bad);
    ASSERT_TRUE(r) << r.error().describe();
    auto t0 = r->read_tile(0, 0);
    ASSERT_FALSE(t0);
    EXPECT_EQ(t0.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(t0.error().message.find("tile (0, 0) checksum"), std::string::npos) << t0.error().message;
    EXPECT_TRUE(r->read_tile(1, 1));
  }
  auto missing = ObsMapReader::open(dir / "missing.vdobs");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
}

TEST(ObsMapFile, OutOfRangeTilesAndTexelsAreErrors) {
  const Fixture f;
  const test::TempDir dir("obsmap_range");
  ASSERT_TRUE(f.write(dir / "m.vdobs", options(ObsCompression::kZstd)));
  auto r = ObsMapReader::open(dir / "m.vdobs");
  ASSERT_TRUE(r);
  for (const auto& [ts, tt] : {std::pair{3, 0}, std::pair{0, 2}, std::pair{-1, 0}}) {
    auto tile = r->read_tile(ts, tt);
    ASSERT_FALSE(tile);
    EXPECT_EQ(tile.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(tile.error().message.find("out of range"), std::string::npos) << tile.error().message;
  }
  EXPECT_FALSE(r->read_tile_of_texel(20, 0));
  auto edge = r->read_tile_of_texel(19, 12);
  ASSERT_TRUE(edge);
  EXPECT_EQ(edge->s0(), 16);
  EXPECT_EQ(edge->width(), 4);
  EXPECT_EQ(edge->height(), 5);
}

TEST(ObsMapFile, WriterMisuseIsAnError) {
  const Fixture f;
  const test::TempDir dir("obsmap_misuse");
  auto w = ObsMapWriter::create(dir / "m.vdobs", f.spec, 11, options(ObsCompression::kNone));
  ASSERT_TRUE(w);
  ASSERT_TRUE(w->add_view(0, f.views[0]));
  EXPECT_EQ(w->add_view(0, f.views[0]).error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(w->add_view(11, f.views[0]).error().code, ErrorCode::kInvalidArgument);
  const Status st = w->finish();
  ASSERT_FALSE(st);
  EXPECT_NE(st.error().message.find("view 1 was never added"), std::string::npos) << st.describe();
  ObsFileOptions o;
  o.tile_size = 0;
  EXPECT_EQ(ObsMapWriter::create(dir / "x.vdobs", f.spec, 11, o).error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(ObsMapWriter::create(dir / "no/such/dir/x.vdobs", f.spec, 11).error().code, ErrorCode::kIo);
}

TEST(ObsMapFile, FullDiskIsNoSpaceAndLeavesThePreviousFileAlone) {
  const Fixture f;
  const test::TempDir dir("obsmap_full");
  const fs::path path = dir / "m.vdobs";
  ASSERT_TRUE(f.write(path, options(ObsCompression::kZstd)));
  const std::vector<char> before = slurp(path);
  // The disk fills at the n-th write: in the spill (views) or while writing the final tiles, index or header.
  for (const int fail_at : {1, 5, 12, 14, 20}) {
    ObsFileOptions o = options(ObsCompression::kNone);
    int writes = 0;
    o.before_write = [&](const fs::path& p, size_t) -> Status {
      if (++writes >= fail_at) return make_error(ErrorCode::kNoSpace, "injected: no space left writing " + p.string());
      return Status::ok();
    };
    const Status st = f.write(path, o);
    ASSERT_FALSE(st) << "fail at write " << fail_at;
    EXPECT_EQ(st.error().code, ErrorCode::kNoSpace);
    EXPECT_EQ(slurp(path), before) << "the published file was touched";
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1) << "temporary files left";
  }
}

// A grazing view's pixel footprint (kObsCoarse, kMaxFootprintTexels): a 32 x 32 map over 1000 mm (31.25 mm texels)
// whose centre texel lies in a disc of radius 45 mm and radiance 0.5 on a surface of 0.05 -- the whole texel is the
// disc's, its corners 22 mm from the centre -- seen from 2000 mm by a 200 x 150, f = 300 camera
// (6.7 mm a pixel square-on), rendered by ray casting one point per pixel as the simulator does. At zenith 84 deg a
// pixel spans 6.7 / cos(84) = 64 mm along the view's azimuth, so the bilinear sample at the texel centre reaches
// past the disc: before kObsCoarse that view was a valid observation of 0.39-0.43 (14-23 % off). At 60 deg (13 mm) the
// sample is the disc's exactly.
TEST(ObsMapFootprint, GrazingViewWiderThanATexelIsNotAnObservation) {
  const ObservationMapSpec spec{32, 32, 1000.0, 1000.0};
  const CameraModel cam{200, 150, 300.0, 300.0, 99.5, 74.5, 0.0, 0.0, 0.0, 0.0, 0.0};
  const rig::RigGeometry geometry{2000.0, Vec3d::Zero()};
  const Vec3d centre = texel_centre_mm(16, 16, 32, 32, 1000.0, 1000.0);
  auto render = [&](double zenith_deg, double pan_deg) {
    ViewInput in;
    in.camera = cam;
    in.pose = rig::surface_pose(geometry, PanTilt{deg_to_rad(pan_deg), deg_to_rad(zenith_deg)});
    in.radiance_bgr.create(cam.height, cam.width, CV_32FC3);
    const Vec3d eye = in.pose.camera_centre();
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const Vec3d ray = in.pose.R.transpose() * cam.pixel_ray(Vec2d(x, y));
        float value = 0.0f;
        if (ray.z() < 0) {
          const Vec3d hit = eye + ray * (-eye.z() / ray.z());
          value = std::hypot(hit.x() - centre.x(), hit.y() - centre.y()) < 45.0 ? 0.5f : 0.05f;
        }
        in.radiance_bgr.at<cv::Vec3f>(y, x) = cv::Vec3f(value, value, value);
      }
    return in;
  };
  for (const double pan : {0.0, 37.0}) {
    const ViewInput grazing = render(84.0, pan);
    // The footprint against its closed form at the surface's centre: distance / (f cos zenith).
    const double distance_mm = (grazing.pose.camera_centre() - centre).norm();
    const double zenith = std::acos(grazing.pose.view_direction(centre).z());
    EXPECT_NEAR(pixel_footprint_mm(cam, grazing.pose, centre) / (distance_mm / (300.0 * std::cos(zenith))), 1.0, 0.02);
    Eigen::Vector3f rgb, dir;
    EXPECT_EQ(observe_texel(spec, grazing, 16, 16, &rgb, &dir), kObsCoarse) << "pan " << pan;
    EXPECT_GT(std::acos(dir.z()) * 180 / kPi, 83.0);  // the direction is kept (plots show where it would have been)
    // What the sample would have been: the surroundings mixed in.
    Eigen::Vector3f mixed;
    const Vec2d px = cam.project(grazing.pose.to_camera(centre));
    ASSERT_TRUE(sample_bilinear(grazing.radiance_bgr, px.x(), px.y(), &mixed));
    EXPECT_LT(mixed.x(), 0.45f);  // measured 0.386 (pan 0), 0.431 (pan 37)
    const ViewInput oblique = render(60.0, pan);
    EXPECT_LT(pixel_footprint_mm(cam, oblique.pose, centre), 15.0);
    ASSERT_EQ(observe_texel(spec, oblique, 16, 16, &rgb, &dir), kObsValid) << "pan " << pan;
    EXPECT_NEAR(rgb.x(), 0.5f, 1e-6f);
    // A map finer than a pixel square-on (256 x 256: 3.9 mm texels against 6.7 mm) keeps its oblique views up to
    // kMaxFootprintStretch times the square-on footprint (about 75 deg), not only those within a texel (none).
    const ObservationMapSpec fine{256, 256, 1000.0, 1000.0};
    EXPECT_EQ(observe_texel(fine, oblique, 128, 128, &rgb, &dir), kObsValid) << "pan " << pan;
    EXPECT_EQ(observe_texel(fine, render(72.0, pan), 128, 128, &rgb, &dir), kObsValid) << "pan " << pan;
    EXPECT_EQ(observe_texel(fine, render(78.0, pan), 128, 128, &rgb, &dir), kObsCoarse) << "pan " << pan;
    EXPECT_EQ(observe_texel(fine, grazing, 128, 128, &rgb, &dir), kObsCoarse) << "pan " << pan;
  }
}

}  // namespace
}  // namespace vdrig::fitting

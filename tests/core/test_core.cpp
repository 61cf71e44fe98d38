// core: conventions, camera model, response curve, settings validation and file I/O.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/settings.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {
namespace fs = std::filesystem;

TEST(Geometry, SphericalRoundTripAndConventions) {
  const Vec3d d = direction_from_spherical(deg_to_rad(30), deg_to_rad(60));
  EXPECT_NEAR(d.norm(), 1.0, 1e-15);
  EXPECT_GT(d.y(), 0);  // azimuth runs from +x toward +y
  const SphericalDir s = spherical_from_direction(d);
  EXPECT_NEAR(rad_to_deg(s.azimuth_rad), 30, 1e-12);
  EXPECT_NEAR(rad_to_deg(s.zenith_rad), 60, 1e-12);
  EXPECT_NEAR(rad_to_deg(spherical_from_direction({0, -1, 0}).azimuth_rad), 270, 1e-12);
}

TEST(Geometry, LatLongSolidAnglesCoverTheSphere) {
  const int W = 64, H = 32;
  double total = 0;
  for (int j = 0; j < H; ++j) total += W * latlong_pixel_solid_angle(j, W, H);
  EXPECT_NEAR(total, 4 * kPi, 1e-12);
  EXPECT_NEAR(latlong_direction(0, 0, W, H).z(), std::cos(kPi * 0.5 / H), 1e-12);  // row 0 looks along +z
}

TEST(Geometry, TexelCentresFollowTheDesignNotes) {
  const Vec3d c = texel_centre_mm(0, 0, 4, 2, 1000, 500);
  EXPECT_DOUBLE_EQ(c.x(), 125 - 500);
  EXPECT_DOUBLE_EQ(c.y(), 125 - 250);
}

TEST(CameraModel, UndistortInvertsDistortAndProjectMatchesRay) {
  CameraModel cam{640, 480, 536, 536, 342, 235, -0.266, -0.0386, 0.0018, -0.00028, 0.238};
  for (double x = -0.5; x <= 0.5; x += 0.1)
    for (double y = -0.4; y <= 0.4; y += 0.1) {
      const Vec2d u(x, y);
      EXPECT_LT((cam.undistort(cam.distort(u)) - u).norm(), 1e-9);
    }
  const Vec3d p(120, -80, 900);
  const Vec2d px = cam.project(p);
  EXPECT_LT(angle_between(cam.pixel_ray(px), p.normalized()), 1e-9);
}

TEST(CameraModel, YamlRoundTripAndBadFiles) {
  const test::TempDir d("core_yaml");
  CameraModel cam{640, 480, 536, 530, 342, 235, -0.2, 0.05, 0.001, -0.002, 0.1};
  ASSERT_TRUE(cam.save_yaml(d / "camera.yml", 0.3));
  auto back = CameraModel::load_yaml(d / "camera.yml");
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_DOUBLE_EQ(back->fy, 530);
  EXPECT_DOUBLE_EQ(back->k3, 0.1);
  EXPECT_EQ(CameraModel::load_yaml(d / "missing.yml").error().code, ErrorCode::kNotFound);
  std::ofstream(d / "bad.yml") << "%YAML:1.0\n---\nimage_width: 10\n";
  EXPECT_EQ(CameraModel::load_yaml(d / "bad.yml").error().code, ErrorCode::kCorrupt);
}

TEST(ResponseCurve, SCurveIsMonotonicAndInverts) {
  const ResponseCurve r = ResponseCurve::s_curve(8);
  EXPECT_EQ(r.forward(0, 0.0), 0.0);
  EXPECT_EQ(r.forward(0, 2.0), 255.0);
  for (int k = 1; k < 255; ++k) {
    ASSERT_GT(r.inverse(0, k), r.inverse(0, k - 1));
    EXPECT_NEAR(r.forward(0, r.inverse(0, k)), k, 1e-9);
  }
  auto j = ResponseCurve::from_json(r.to_json());
  ASSERT_TRUE(j);
  EXPECT_DOUBLE_EQ(j->inverse(1, 100.5), r.inverse(1, 100.5));
  std::array<std::vector<double>, 3> bad{std::vector<double>(256, 0.5), std::vector<double>(256, 0.5),
                                         std::vector<double>(10, 0.0)};
  EXPECT_FALSE(ResponseCurve::from_inverse(8, bad));
}

TEST(ImageIo, ExrRoundTripKeepsChannelsAndAttributes) {
  const test::TempDir d("core_exr");
  ExrImage img;
  cv::Mat a(3, 5, CV_32FC1), b(3, 5, CV_32FC1);
  cv::randu(a, -10, 1e4);
  cv::randu(b, 0, 1);
  img.add("kd.R", a);
  img.add("m", b);
  img.string_attributes["vdrig.model"] = "phong";
  img.number_attributes["vdrig.lobes"] = 2;
  for (ExrPixelType type : {ExrPixelType::kFloat, ExrPixelType::kHalf}) {
    ASSERT_TRUE(write_exr(d / "x.exr", img, type));
    auto back = read_exr(d / "x.exr");
    ASSERT_TRUE(back) << back.error().describe();
    ASSERT_EQ(back->find("m"), 1);
    const double tol = type == ExrPixelType::kFloat ? 0.0 : 1e-3;  // half: 11-bit mantissa
    EXPECT_LE(cv::norm(back->channels[1], b, cv::NORM_INF), tol);
    EXPECT_LE(cv::norm(back->channels[0], a, cv::NORM_INF | cv::NORM_RELATIVE), tol);
    EXPECT_EQ(back->string_attributes.at("vdrig.model"), "phong");
    EXPECT_EQ(back->number_attributes.at("vdrig.lobes"), 2);
  }
  // A truncated file is an error value, not a crash.
  const auto size = fs::file_size(d / "x.exr");
  fs::resize_file(d / "x.exr", size / 2);
  EXPECT_EQ(read_exr(d / "x.exr").error().code, ErrorCode::kCorrupt);
  std::ofstream(d / "text.exr") << "not an exr";
  EXPECT_EQ(read_exr(d / "text.exr").error().code, ErrorCode::kCorrupt);
  EXPECT_EQ(read_exr(d / "none.exr").error().code, ErrorCode::kNotFound);
}

TEST(ImageIo, AtomicWriteLeavesNoTemporaryAndReportsBadFolders) {
  const test::TempDir d("core_atomic");
  ASSERT_TRUE(write_file_atomic(d / "a.txt", "hello"));
  ASSERT_TRUE(write_file_atomic(d / "a.txt", "world"));
  std::ifstream in(d / "a.txt");
  std::string s;
  in >> s;
  EXPECT_EQ(s, "world");
  int files = 0;
  for (const auto& e : fs::directory_iterator(d)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  EXPECT_FALSE(write_file_atomic(d / "no" / "such" / "dir.txt", "x"));
  EXPECT_FALSE(write_png(d / "empty.png", cv::Mat()));
}

TEST(Settings, CollectsEveryProblemAndAcceptsTheEnvelope) {
  const nlohmann::json section = {{"backend", "x"},   {"speed", "fast"}, {"count", 2.5}, {"offsets", {1, 2}},
                                  {"calls", {3, -1}}, {"name", "a"},     {"typo", true}, {"ok", 4}};
  Settings s(section, "stage demo", {"backend"});
  EXPECT_EQ(s.number("speed", 1.0), 1.0);  // fallback on a problem
  EXPECT_EQ(s.integer("count", 7, 0, 10), 7);
  EXPECT_EQ(s.number_list("offsets", {0, 0, 0}, 3).size(), 3u);
  EXPECT_TRUE(s.unsigned_list("calls", {}).empty());
  EXPECT_EQ(s.integer("ok", 0, 0, 10), 4);
  EXPECT_EQ(s.unsigned_integer("absent", 9), 9u);
  EXPECT_EQ(s.string("name", "", {"a", "b"}), "a");
  s.reject_unknown({"speed", "count", "offsets", "calls", "name", "ok"});
  std::string why;
  ASSERT_FALSE(s.is_valid(&why));
  EXPECT_EQ(s.problems().size(), 5u) << why;
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(why.rfind("stage demo: invalid settings; ", 0), 0u) << why;
  for (const char* part :
       {"\"speed\" must be a number", "\"count\" must be an integer", "\"offsets\" must be an array of 3",
        "\"calls\" must be an array of non-negative integers", "unknown setting \"typo\""})
    EXPECT_NE(why.find(part), std::string::npos) << part << " not in: " << why;
  EXPECT_EQ(s.reasons().find("stage demo"), std::string::npos);  // reasons alone, for callers that frame them

  Settings request({{"cmd", "move"}, {"id", 1}, {"extra", 0}}, "request", {"cmd", "id"});
  request.reject_unknown(std::vector<std::string>{"pan_deg"}, "field");
  EXPECT_EQ(request.reasons(), "unknown field \"extra\"");
  Settings not_object(nlohmann::json::array(), "sim");
  EXPECT_FALSE(not_object.is_valid(nullptr));
}

TEST(FileIo, ErrnoMapsToNoSpaceOnlyForAFullDiskOrQuota) {
  EXPECT_EQ(error_code_from_errno(ENOSPC), ErrorCode::kNoSpace);
  EXPECT_EQ(error_code_from_errno(EDQUOT), ErrorCode::kNoSpace);
  for (int err : {EIO, EACCES, ENOENT, EROFS, 0}) EXPECT_EQ(error_code_from_errno(err), ErrorCode::kIo) << err;
  const Error e = error_from_errno(ENOSPC, "write /x/y");
  EXPECT_EQ(e.code, ErrorCode::kNoSpace);
  EXPECT_EQ(e.message, std::string("write /x/y: ") + std::strerror(ENOSPC));
}

TEST(FileIo, FsyncPathSyncsFilesAndFoldersAndNamesWhatFailed) {
  const test::TempDir d("core_fsync");
  ASSERT_TRUE(write_file_atomic(d / "a.txt", "a"));
  EXPECT_TRUE(fsync_path(d / "a.txt", false));
  EXPECT_TRUE(fsync_path(d, true));
  const Status missing = fsync_path(d / "missing", false);
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kIo);
  EXPECT_NE(missing.error().message.find((d / "missing").string()), std::string::npos) << missing.describe();
  EXPECT_FALSE(fsync_path(d / "a.txt", true));  // not a folder
}

TEST(FileIo, AtomicWritesNeverReplaceADeviceFifoOrFolder) {
  // Renaming over a special file replaces it: `--out /dev/null` run as root used to turn /dev/null into a file.
  const test::TempDir d("core_replace_special");
  const fs::path fifo = d / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const Status on_fifo = write_file_atomic(fifo, "x");
  ASSERT_FALSE(on_fifo);
  EXPECT_EQ(on_fifo.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(on_fifo.error().message.find("not a regular file"), std::string::npos) << on_fifo.describe();
  EXPECT_TRUE(fs::is_fifo(fifo));
  fs::create_directories(d / "folder.png");
  EXPECT_FALSE(write_png(d / "folder.png", cv::Mat(2, 2, CV_8UC3, cv::Scalar::all(7))));
  EXPECT_TRUE(fs::is_directory(d / "folder.png"));
  int files = 0;  // no temporary left behind
  for (const auto& e : fs::directory_iterator(d.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 0);
  EXPECT_TRUE(write_file_atomic(d / "plain.txt", "a"));
  EXPECT_TRUE(write_file_atomic(d / "plain.txt", "b"));  // a regular file is replaced as before
}

TEST(FileIo, WriteAllWritesEverythingAndReportsAFullDevice) {
  const test::TempDir d("core_write_all");
  const std::string text(1 << 20, 'x');
  const int fd = ::open((d / "big").c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  EXPECT_EQ(write_all(fd, text.data(), text.size()), 0);
  ::close(fd);
  EXPECT_EQ(fs::file_size(d / "big"), text.size());
  // /dev/full fails every write with ENOSPC: the disk-full path without filling a disk.
  const int full = ::open("/dev/full", O_WRONLY | O_CLOEXEC);
  if (full < 0) GTEST_SKIP() << "no /dev/full";
  EXPECT_EQ(write_all(full, text.data(), 16), ENOSPC);
  ::close(full);
}

}  // namespace
}  // namespace vdrig

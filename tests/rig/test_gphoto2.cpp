// The gphoto2 camera backend (its pure label reading is test_gphoto2_labels.cpp):
//  - its settings, validated up front, and its errors;
//  - the backend through the real libgphoto2 stack against its "Directory Browse" camlib (port "disk:FOLDER"),
//    a peer this project did not write: it presents a folder as a camera. In libgphoto2 2.5.30 it has no
//    configuration and no capture (both GP_ERROR_NOT_SUPPORTED), so it exercises open, the unsupported paths, file
//    listing, download, delete, decoding and the error paths; remote capture and settings are unit-tested only.
// A real camera, when one is attached, is tested by RealCamera (skipped otherwise).
#include <gtest/gtest.h>

#ifdef VDRIG_HAVE_GPHOTO2

#include <gphoto2/gphoto2-port-result.h>
#include <gphoto2/gphoto2-result.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "gphoto2_camera.hpp"
#include "vdrig/rig/registry.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rig {
namespace {
namespace fs = std::filesystem;

TEST(Gphoto2Config, SettingsAreValidatedUpFront) {
  auto bad = Gphoto2Config::parse({{"model", "Canon EOS 600D"},
                                   {"index", -1},
                                   {"capture_target", "sdram"},
                                   {"base_iso", 0},
                                   {"aperture", "f/8"},
                                   {"shutter", 1}});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  for (const char* key : {"port", "index", "capture_target", "base_iso", "aperture", "shutter"})
    EXPECT_NE(bad.error().message.find(key), std::string::npos) << key << " in: " << bad.error().message;
  auto good = Gphoto2Config::parse({{"model", "Nikon DSC D750"}, {"port", "usb:001,007"}, {"aperture", 8}});
  ASSERT_TRUE(good) << good.error().describe();
  EXPECT_EQ(good->capture_target, Gphoto2Config::Target::kRam);
  EXPECT_EQ(good->aperture, 8.0);
  EXPECT_FALSE(good->keep_on_card);
}

TEST(Gphoto2Errors, TypedAndNamingTheHolders) {
  const Error busy = gphoto2_error(GP_ERROR_IO_USB_CLAIM, "cannot open Canon EOS 600D on usb:001,007", false);
  EXPECT_EQ(busy.code, ErrorCode::kDevice);
  for (const char* holder : {"gvfs-gphoto2-volume-monitor", "gphoto2", "Shotwell", "docs/hardware.md"})
    EXPECT_NE(busy.message.find(holder), std::string::npos) << holder << " in: " << busy.message;
  EXPECT_EQ(gphoto2_error(GP_ERROR_IO_USB_FIND, "x", false).code, ErrorCode::kNotFound);
  EXPECT_EQ(gphoto2_error(GP_ERROR_IO_USB_FIND, "x", true).code, ErrorCode::kDisconnected);
  EXPECT_EQ(gphoto2_error(GP_ERROR_IO, "x", true).code, ErrorCode::kDisconnected);
  EXPECT_EQ(gphoto2_error(GP_ERROR_TIMEOUT, "x", true).code, ErrorCode::kTimeout);
  EXPECT_EQ(gphoto2_error(GP_ERROR_MODEL_NOT_FOUND, "x", false).code, ErrorCode::kNotFound);
  EXPECT_EQ(gphoto2_error(GP_ERROR_NOT_SUPPORTED, "x", true).code, ErrorCode::kUnsupported);
  const Error ctx = gphoto2_error(GP_ERROR, "capture", true, "PTP Store Not Available\n");
  EXPECT_EQ(ctx.code, ErrorCode::kDevice);
  EXPECT_NE(ctx.message.find("PTP Store Not Available"), std::string::npos);
}

// ---- through libgphoto2's directory camlib ----

cv::Mat pattern(int w, int h) {
  cv::Mat m(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      m.at<cv::Vec3b>(y, x) = cv::Vec3b(uint8_t(20 + x * 200 / w), uint8_t(30 + y * 190 / h), uint8_t(128));
  cv::circle(m, {w / 3, h / 2}, h / 5, cv::Scalar(240, 240, 20), cv::FILLED);
  return m;
}

void write_bytes(const fs::path& p, const std::vector<uint8_t>& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

class DirectoryCamlib : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(folder_);
    std::vector<uint8_t> jpeg;
    ASSERT_TRUE(cv::imencode(".jpg", image_, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
    write_bytes(folder_ / "IMG_0001.JPG", jpeg);
    decoded_ = cv::imdecode(jpeg, cv::IMREAD_COLOR);
  }
  /// The frame is the file's exact decode (libgphoto2 moved the bytes unchanged) and looks like the pattern.
  void expect_the_photo(const Frame& frame) {
    ASSERT_EQ(frame.image.size(), image_.size());
    ASSERT_EQ(frame.image.type(), CV_8UC3);
    EXPECT_EQ(cv::norm(frame.image, decoded_, cv::NORM_INF), 0.0);
    EXPECT_GT(cv::PSNR(frame.image, image_), 30.0);
  }
  Result<std::unique_ptr<Gphoto2Camera>> open(nlohmann::json extra = nlohmann::json::object()) {
    extra["model"] = "Directory Browse";
    extra["port"] = "disk:" + folder_.string();
    auto c = Gphoto2Config::parse(extra);
    if (!c) return c.error();
    return Gphoto2Camera::open(c.value());
  }
  const StillFile* find(const std::vector<StillFile>& files, const std::string& name) {
    for (const auto& f : files)
      if (f.name == name) return &f;
    return nullptr;
  }

  test::TempDir dir_{"gphoto2"};
  fs::path folder_ = dir_.path() / "camera";
  cv::Mat image_ = pattern(160, 120);
  cv::Mat decoded_;
};

TEST_F(DirectoryCamlib, OpensListsDownloadsDecodesAndDeletes) {
  auto cam = open();
  ASSERT_TRUE(cam) << cam.error().describe();
  auto info = (*cam)->info();
  ASSERT_TRUE(info);
  EXPECT_EQ(info->model, "Directory Browse");
  EXPECT_TRUE(info->auto_exposure_on);    // no shutter speed to set
  EXPECT_TRUE((*cam)->config().empty());  // the directory camlib has no configuration
  EXPECT_EQ((*cam)->backend(), "gphoto2");

  auto files = (*cam)->list_files("/");
  ASSERT_TRUE(files) << files.error().describe();
  ASSERT_EQ(files->size(), 1u);
  EXPECT_EQ(files->front().name, "IMG_0001.JPG");
  EXPECT_TRUE(files->front().decodable);
  auto frame = (*cam)->collect(files.value());
  ASSERT_TRUE(frame) << frame.error().describe();
  expect_the_photo(frame.value());
  EXPECT_EQ(frame->bits, 8);
  EXPECT_FALSE(fs::exists(folder_ / "IMG_0001.JPG"));  // deleted from the "camera" once decoded
  EXPECT_EQ((*cam)->info()->width, 160);
  ASSERT_TRUE((*cam)->list_files("/"));
  EXPECT_TRUE((*cam)->list_files("/")->empty());
}

TEST_F(DirectoryCamlib, KeepOnCardAndRawOnlyLoseNothing) {
  std::vector<uint8_t> raw(4096, 0x42);
  write_bytes(folder_ / "IMG_0002.CR2", raw);
  auto cam = open({{"keep_on_card", true}});
  ASSERT_TRUE(cam) << cam.error().describe();
  auto files = (*cam)->list_files("/");
  ASSERT_TRUE(files) << files.error().describe();
  const StillFile* jpg = find(*files, "IMG_0001.JPG");
  const StillFile* cr2 = find(*files, "IMG_0002.CR2");
  ASSERT_TRUE(jpg && cr2) << files->size() << " files listed";
  EXPECT_FALSE(cr2->decodable);
  auto frame = (*cam)->collect({*cr2, *jpg});  // RAW+JPEG: the JPEG is used
  ASSERT_TRUE(frame) << frame.error().describe();
  expect_the_photo(frame.value());
  EXPECT_TRUE(fs::exists(folder_ / "IMG_0001.JPG"));  // kept
  EXPECT_TRUE(fs::exists(folder_ / "IMG_0002.CR2"));

  auto cam2 = open();  // deleting camera: a RAW-only shot is refused and stays on the camera
  ASSERT_TRUE(cam2);
  auto raw_only = (*cam2)->collect({*cr2});
  ASSERT_FALSE(raw_only);
  EXPECT_EQ(raw_only.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(raw_only.error().message.find("RAW only"), std::string::npos) << raw_only.error().message;
  EXPECT_TRUE(fs::exists(folder_ / "IMG_0002.CR2"));
}

TEST_F(DirectoryCamlib, CorruptJpegIsKCorruptAndStaysOnTheCamera) {
  std::vector<uint8_t> bad(3000, 0x5A);  // a JPEG's first bytes (SOI, APP0 marker), then junk
  bad[0] = 0xFF;
  bad[1] = 0xD8;
  bad[2] = 0xFF;
  bad[3] = 0xE0;
  write_bytes(folder_ / "IMG_0003.JPG", bad);
  auto cam = open();
  ASSERT_TRUE(cam) << cam.error().describe();
  auto files = (*cam)->list_files("/");
  ASSERT_TRUE(files);
  const StillFile* f = find(*files, "IMG_0003.JPG");
  ASSERT_TRUE(f);
  auto frame = (*cam)->collect({*f});
  ASSERT_FALSE(frame);
  EXPECT_EQ(frame.error().code, ErrorCode::kCorrupt) << frame.error().describe();
  EXPECT_NE(frame.error().message.find("IMG_0003.JPG"), std::string::npos);
  EXPECT_TRUE(fs::exists(folder_ / "IMG_0003.JPG"));
}

TEST_F(DirectoryCamlib, NoSettingsNoCaptureAreUnsupportedNotFaked) {
  auto cam = open();
  ASSERT_TRUE(cam) << cam.error().describe();
  const Status s = (*cam)->set_exposure(0.01, 1.0);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(s.error().message.find("shutterspeed"), std::string::npos) << s.error().message;
  // libgphoto2 2.5.30's directory camlib cannot capture: the backend says so instead of returning a stored file.
  auto frame = (*cam)->capture();
  ASSERT_FALSE(frame);
  EXPECT_EQ(frame.error().code, ErrorCode::kUnsupported) << frame.error().describe();
  EXPECT_TRUE(fs::exists(folder_ / "IMG_0001.JPG"));
  EXPECT_FALSE((*cam)->set_exposure(-1.0, 1.0));
}

TEST_F(DirectoryCamlib, FolderRemovedMidSessionIsKDisconnectedThenReopens) {
  auto cam = open();
  ASSERT_TRUE(cam) << cam.error().describe();
  auto files = (*cam)->list_files("/");
  ASSERT_TRUE(files);
  ASSERT_EQ(files->size(), 1u);
  const std::vector<uint8_t> keep = [&] {
    std::ifstream in(folder_ / "IMG_0001.JPG", std::ios::binary);
    return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
  }();
  fs::remove_all(folder_);  // the "camera" goes away between listing and download
  auto frame = (*cam)->collect(files.value());
  ASSERT_FALSE(frame);
  EXPECT_EQ(frame.error().code, ErrorCode::kDisconnected) << frame.error().describe();
  // Back: the next call reopens the camera and works again.
  fs::create_directories(folder_);
  write_bytes(folder_ / "IMG_0001.JPG", keep);
  files = (*cam)->list_files("/");
  ASSERT_TRUE(files) << files.error().describe();
  ASSERT_EQ(files->size(), 1u);
  frame = (*cam)->collect(files.value());
  ASSERT_TRUE(frame) << frame.error().describe();
  expect_the_photo(frame.value());
}

TEST(Gphoto2Open, MissingModelPortOrCameraIsKNotFound) {
  auto model = Gphoto2Camera::open(Gphoto2Config::parse({{"model", "No Such Camera 9000"}, {"port", "usb:"}}).value());
  ASSERT_FALSE(model);
  EXPECT_EQ(model.error().code, ErrorCode::kNotFound) << model.error().describe();
  EXPECT_NE(model.error().message.find("No Such Camera 9000"), std::string::npos);
  // A real driver on a USB address where nothing is attached.
  auto port = Gphoto2Camera::open(Gphoto2Config::parse({{"model", "Canon EOS 600D"}, {"port", "usb:250,127"}}).value());
  ASSERT_FALSE(port);
  EXPECT_EQ(port.error().code, ErrorCode::kNotFound) << port.error().describe();

  auto detected = list_gphoto2_cameras();
  ASSERT_TRUE(detected) << detected.error().describe();
  if (!detected->empty()) GTEST_SKIP() << detected->size() << " camera(s) attached: no \"none found\" case here";
  auto none = Gphoto2Camera::open(Gphoto2Config{});
  ASSERT_FALSE(none);
  EXPECT_EQ(none.error().code, ErrorCode::kNotFound) << none.error().describe();
  EXPECT_NE(none.error().message.find("0 camera(s)"), std::string::npos) << none.error().message;
}

TEST(Gphoto2Open, RegisteredAsACameraBackend) {
  BackendRegistry registry;
  register_hardware_backends(registry);
  const auto names = registry.camera_backends();
  EXPECT_NE(std::find(names.begin(), names.end(), "gphoto2"), names.end());
}

// A camera libgphoto2 finds: open it, take a photo at two exposures, check the frames report what was set.
TEST(Gphoto2RealCamera, CapturesAtTheNearestStops) {
  auto detected = list_gphoto2_cameras();
  ASSERT_TRUE(detected) << detected.error().describe();
  // A mounted card shows up as "Mass Storage Camera" (the directory camlib): no shutter there.
  std::erase_if(*detected, [](const Gphoto2Detected& d) { return d.model == "Mass Storage Camera"; });
  if (detected->empty()) GTEST_SKIP() << "no camera attached that libgphoto2 finds";
  Gphoto2Config config;
  config.model = detected->front().model;
  config.port = detected->front().port;
  auto cam = Gphoto2Camera::open(config);
  ASSERT_TRUE(cam) << cam.error().describe();
  for (double exposure_s : {1.0 / 100, 1.0 / 25}) {
    ASSERT_TRUE((*cam)->set_exposure(exposure_s, 1.0));
    auto frame = (*cam)->capture();
    ASSERT_TRUE(frame) << frame.error().describe();
    EXPECT_FALSE(frame->image.empty());
    EXPECT_LT(std::abs(std::log2(frame->exposure_s / exposure_s)), 0.5);  // within half a stop of what was asked
  }
}

}  // namespace
}  // namespace vdrig::rig

#else
TEST(Gphoto2, NotBuilt) { GTEST_SKIP() << "built without libgphoto2 (VDRIG_WITH_GPHOTO2=OFF)"; }
#endif

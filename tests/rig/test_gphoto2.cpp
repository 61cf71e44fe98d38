// The gphoto2 camera backend. Two parts:
//  - pure code (no camera, no libgphoto2 call): gphoto2's shutter/ISO/aperture labels, the nearest stop, and which
//    config names each vendor's driver uses (camlibs/ptp2/config.c of libgphoto2), on configs modelled on those;
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

// ---- labels ----

TEST(Gphoto2Labels, ShutterSpeedsInEveryVendorsSpelling) {
  const std::vector<std::pair<const char*, double>> good = {
      {"1/250", 1.0 / 250}, {"1/3", 1.0 / 3},     {"2", 2.0},         {"0.5", 0.5},
      {"1\"3", 1.3},        {"30\"", 30.0},       {"0.0080s", 0.008}, {"1/4000", 0.00025},
      {"10/1250", 0.008},   {" 1/60 ", 1.0 / 60}, {"2.5", 2.5},       {"0\"5", 0.5}};
  for (const auto& [label, seconds] : good) {
    const auto v = parse_shutter_label(label);
    ASSERT_TRUE(v) << label;
    EXPECT_NEAR(*v, seconds, 1e-12) << label;
  }
  for (const char* label : {"bulb", "Bulb", "BULB", "Time", "x 200", "Auto", "", "1/0", "-1", "1/", "/250", "0",
                            "1.5\"3", "1e-3", "1/250x"})
    EXPECT_FALSE(parse_shutter_label(label)) << "\"" << label << "\" read as " << *parse_shutter_label(label);
}

TEST(Gphoto2Labels, IsoAndAperture) {
  EXPECT_EQ(parse_iso_label("100"), 100.0);
  EXPECT_EQ(parse_iso_label("ISO 200"), 200.0);
  EXPECT_EQ(parse_iso_label("25600"), 25600.0);
  for (const char* label : {"Auto", "Auto ISO", "auto", "Hi 1", "Lo 1", "", "0"})
    EXPECT_FALSE(parse_iso_label(label)) << label;
  EXPECT_EQ(parse_aperture_label("f/5.6"), 5.6);
  EXPECT_EQ(parse_aperture_label("5.6"), 5.6);
  EXPECT_EQ(parse_aperture_label("F8"), 8.0);
  EXPECT_EQ(parse_aperture_label("f/22"), 22.0);
  for (const char* label : {"implicit auto", "f/", "", "f/-2"}) EXPECT_FALSE(parse_aperture_label(label)) << label;
}

// Canon EOS's shutter choices as libgphoto2 lists them (bulb first).
const std::vector<std::string> kCanonShutter = {
    "bulb",  "30",    "25",     "20",     "15",     "13",     "10",     "8",      "6",     "5",     "4",
    "3.2",   "2.5",   "2",      "1.6",    "1.3",    "1",      "0.8",    "0.6",    "0.5",   "0.4",   "0.3",
    "1/4",   "1/5",   "1/6",    "1/8",    "1/10",   "1/13",   "1/15",   "1/20",   "1/25",  "1/30",  "1/40",
    "1/50",  "1/60",  "1/80",   "1/100",  "1/125",  "1/160",  "1/200",  "1/250",  "1/320", "1/400", "1/500",
    "1/640", "1/800", "1/1000", "1/1250", "1/1600", "1/2000", "1/2500", "1/3200", "1/4000"};

TEST(Gphoto2Labels, NearestStopAndTheExposureReallySet) {
  // 7.5 ms: 1/125 is 0.093 stops off, 1/160 is 0.263 (log2(7.5/6.25)).
  auto c = choose_stop(kCanonShutter, 0.0075, parse_shutter_label);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->label, "1/125");
  EXPECT_DOUBLE_EQ(c->value, 0.008);
  EXPECT_EQ(kCanonShutter[c->index], "1/125");
  // Longer than anything: the longest timed exposure, never bulb; shorter than anything: the shortest.
  EXPECT_EQ(choose_stop(kCanonShutter, 1e6, parse_shutter_label)->label, "30");
  EXPECT_EQ(choose_stop(kCanonShutter, 1e-9, parse_shutter_label)->label, "1/4000");
  // Nearest in stops, not in seconds: 0.55 s is 0.30 s from 1/4 and 0.45 s from 1, but 1.14 vs 0.86 stops.
  EXPECT_EQ(choose_stop({"1/4", "1"}, 0.55, parse_shutter_label)->label, "1");
  const std::vector<std::string> iso = {"Auto", "100", "200", "400", "800", "1600", "3200", "6400"};
  EXPECT_EQ(choose_stop(iso, 300, parse_iso_label)->label, "400");  // 0.415 stops; 200 is 0.585
  EXPECT_EQ(choose_stop(iso, 10, parse_iso_label)->label, "100");
  EXPECT_FALSE(choose_stop({"Auto", "bulb"}, 100, parse_iso_label));
  EXPECT_FALSE(choose_stop(iso, -1, parse_iso_label));
  const auto range = stop_range(kCanonShutter, parse_shutter_label);
  ASSERT_TRUE(range);
  EXPECT_DOUBLE_EQ(range->first, 1.0 / 4000);
  EXPECT_DOUBLE_EQ(range->second, 30.0);
}

TEST(StillCameraStops, NearestStopSkipsWhatIsNoExposure) {
  EXPECT_EQ(nearest_stop({0.0, -1.0, NAN, 0.01, INFINITY}, 1.0), 3u);
  EXPECT_EQ(nearest_stop({0.5, 2.0}, 1.0), 0u);  // a tie: the first listed
  EXPECT_FALSE(nearest_stop({0.0, NAN}, 1.0));
  EXPECT_FALSE(nearest_stop({1.0}, 0.0));
  EXPECT_TRUE(is_decodable_image_name("IMG_0001.JPG"));
  EXPECT_TRUE(is_decodable_image_name("a.tiff"));
  EXPECT_FALSE(is_decodable_image_name("IMG_0001.CR2"));
  EXPECT_FALSE(is_decodable_image_name("DSC_0001.NEF"));
  EXPECT_FALSE(is_decodable_image_name("jpg"));
}

// ---- config names across vendors ----

ConfigEntry entry(std::string name, std::vector<std::string> choices, std::string value, bool readonly = false) {
  ConfigEntry e;
  e.name = std::move(name);
  e.choices = std::move(choices);
  e.value = std::move(value);
  e.readonly = readonly;
  return e;
}

TEST(Gphoto2Config, SettingNamesOfCanonNikonAndSony) {
  // Canon EOS: shutterspeed / iso / aperture, capturetarget "Internal RAM" / "Memory card".
  const std::vector<ConfigEntry> canon = {entry("capturetarget", {"Internal RAM", "Memory card"}, "Memory card"),
                                          entry("shutterspeed", kCanonShutter, "1/60"),
                                          entry("iso", {"Auto", "100", "200", "400"}, "Auto"),
                                          entry("aperture", {"4", "5.6", "8", "11"}, "5.6")};
  EXPECT_EQ(find_setting(canon, StillSetting::kShutter, parse_shutter_label)->name, "shutterspeed");
  EXPECT_EQ(find_setting(canon, StillSetting::kIso, parse_iso_label)->name, "iso");
  EXPECT_EQ(find_setting(canon, StillSetting::kAperture, parse_aperture_label)->name, "aperture");
  EXPECT_EQ(choose_capture_target(find_setting(canon, StillSetting::kCaptureTarget)->choices, true), "Internal RAM");
  EXPECT_EQ(choose_capture_target(find_setting(canon, StillSetting::kCaptureTarget)->choices, false), "Memory card");

  // Nikon: the generic ExposureTime ("shutterspeed", in "0.0080s" form) read-only outside M, the vendor's
  // "shutterspeed2" writable; "f-number"; SDRAM / Card targets.
  const std::vector<ConfigEntry> nikon = {
      entry("shutterspeed", {"0.0010s", "0.0080s", "1.0000s"}, "0.0080s", /*readonly=*/true),
      entry("shutterspeed2", {"1/1000", "1/125", "1", "30", "Bulb", "x 200"}, "1/125"),
      entry("f-number", {"f/3.5", "f/5.6", "f/8"}, "f/5.6"), entry("iso", {"100", "200", "400"}, "200"),
      entry("capturetarget", {"SDRAM", "Card"}, "Card")};
  EXPECT_EQ(find_setting(nikon, StillSetting::kShutter, parse_shutter_label)->name, "shutterspeed2");
  EXPECT_EQ(find_setting(nikon, StillSetting::kAperture, parse_aperture_label)->name, "f-number");
  EXPECT_EQ(choose_capture_target(nikon.back().choices, true), "SDRAM");
  EXPECT_EQ(choose_capture_target(nikon.back().choices, false), "Card");
  EXPECT_EQ(choose_stop(nikon[1].choices, 20.0, parse_shutter_label)->label, "30");  // never "Bulb" or "x 200"

  // Sony: shutterspeed with seconds marks, iso with "Auto ISO", f-number.
  const std::vector<ConfigEntry> sony = {entry("shutterspeed", {"30\"", "1\"3", "1/250", "Bulb"}, "1/250"),
                                         entry("iso", {"Auto ISO", "100", "800"}, "Auto ISO"),
                                         entry("f-number", {"f/2.8", "f/4"}, "f/4")};
  EXPECT_EQ(
      choose_stop(find_setting(sony, StillSetting::kShutter, parse_shutter_label)->choices, 1.0, parse_shutter_label)
          ->label,
      "1\"3");
  EXPECT_EQ(find_setting(sony, StillSetting::kAperture, parse_aperture_label)->name, "f-number");

  // A camera in an automatic mode (everything read-only) or one whose ISO is Auto only: nothing to set.
  const std::vector<ConfigEntry> automatic = {entry("shutterspeed", kCanonShutter, "1/60", true),
                                              entry("iso", {"Auto"}, "Auto")};
  EXPECT_EQ(find_setting(automatic, StillSetting::kShutter, parse_shutter_label), nullptr);
  EXPECT_EQ(find_setting(automatic, StillSetting::kIso, parse_iso_label), nullptr);
  EXPECT_EQ(find_setting({}, StillSetting::kCaptureTarget), nullptr);
  EXPECT_FALSE(choose_capture_target({"Memory card"}, true));
}

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

// Camera backends: the pure pieces (buffer -> BGR conversion, V4L2 exposure units) on synthetic data, and the
// hardware paths, each skipped when this machine has no such device.
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "pixel_convert.hpp"
#include "vdrig/rig/registry.hpp"
#ifdef VDRIG_HAVE_USB
#include "usb_ptp_camera.hpp"
#endif

namespace vdrig::rig {
namespace {

cv::Mat gradient_bgr(int w, int h) {
  cv::Mat m(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      m.at<cv::Vec3b>(y, x) = cv::Vec3b(uint8_t(40 + 3 * x), uint8_t(60 + 2 * y), uint8_t(200 - x - y));
  return m;
}

double max_abs_diff(const cv::Mat& a, const cv::Mat& b) { return cv::norm(a, b, cv::NORM_INF); }

TEST(PixelConvert, PackedRgbLayoutsWithPaddedStride) {
  const cv::Mat bgr = gradient_bgr(10, 6);
  // RGB24 in a buffer with 8 bytes of padding per line.
  const size_t stride = 10 * 3 + 8;
  std::vector<uint8_t> buf(stride * 6, 0xee);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  for (int y = 0; y < 6; ++y) std::memcpy(&buf[y * stride], rgb.ptr(y), 30);
  auto out = to_bgr({buf.data(), buf.size(), 10, 6, stride, PixelLayout::kRGB24, 8});
  ASSERT_TRUE(out) << out.error().describe();
  EXPECT_EQ(out->type(), CV_8UC3);
  EXPECT_EQ(max_abs_diff(*out, bgr), 0.0);
  // BGRX32 packed.
  cv::Mat bgrx;
  cv::cvtColor(bgr, bgrx, cv::COLOR_BGR2BGRA);
  out = to_bgr({bgrx.data, bgrx.total() * 4, 10, 6, 0, PixelLayout::kBGRX32, 8});
  ASSERT_TRUE(out);
  EXPECT_EQ(max_abs_diff(*out, bgr), 0.0);
  // A buffer one byte short is corrupt, not read past its end.
  auto short_buf = to_bgr({buf.data(), stride * 5 + 29, 10, 6, stride, PixelLayout::kRGB24, 8});
  ASSERT_FALSE(short_buf);
  EXPECT_EQ(short_buf.error().code, ErrorCode::kCorrupt);
}

TEST(PixelConvert, YuvLayoutsDecodeToTheColours) {
  // A smooth image through I420 -> NV12 (interleave U, V) -> our conversion comes back within chroma rounding.
  const cv::Mat bgr = gradient_bgr(16, 8);
  cv::Mat i420;
  cv::cvtColor(bgr, i420, cv::COLOR_BGR2YUV_I420);
  std::vector<uint8_t> nv12(16 * 8 * 3 / 2);
  std::memcpy(nv12.data(), i420.data, 16 * 8);
  const uint8_t* u = i420.data + 16 * 8;
  const uint8_t* v = u + 8 * 4;
  for (int i = 0; i < 8 * 4; ++i) nv12[16 * 8 + 2 * i] = u[i], nv12[16 * 8 + 2 * i + 1] = v[i];
  auto out = to_bgr({nv12.data(), nv12.size(), 16, 8, 0, PixelLayout::kNV12, 8});
  ASSERT_TRUE(out) << out.error().describe();
  EXPECT_LE(max_abs_diff(*out, bgr), 8.0);

  // YUYV / UYVY: a grey pixel pair (U = V = 128) is grey; a high V (red-difference) makes red exceed blue.
  const uint8_t yuyv[] = {128, 128, 128, 128, 100, 90, 100, 220};
  auto g = to_bgr({yuyv, sizeof yuyv, 4, 1, 0, PixelLayout::kYUYV, 8});
  ASSERT_TRUE(g);
  const cv::Vec3b p0 = g->at<cv::Vec3b>(0, 0), p2 = g->at<cv::Vec3b>(0, 2);
  EXPECT_EQ(p0[0], p0[1]);
  EXPECT_EQ(p0[1], p0[2]);
  EXPECT_GT(p2[2], p2[0] + 100);
  const uint8_t uyvy[] = {128, 128, 128, 128, 90, 100, 220, 100};  // the same pixels, other byte order
  auto g2 = to_bgr({uyvy, sizeof uyvy, 4, 1, 0, PixelLayout::kUYVY, 8});
  ASSERT_TRUE(g2);
  EXPECT_EQ(max_abs_diff(*g, *g2), 0.0);
  EXPECT_EQ(to_bgr({yuyv, sizeof yuyv, 3, 1, 0, PixelLayout::kYUYV, 8}).error().code, ErrorCode::kInvalidArgument);
}

TEST(PixelConvert, Grey16KeepsCodesAndMjpegDecodes) {
  const uint16_t y12[] = {0, 4095, 1234, 77};
  auto out = to_bgr({reinterpret_cast<const uint8_t*>(y12), sizeof y12, 2, 2, 0, PixelLayout::kGrey16, 12});
  ASSERT_TRUE(out);
  EXPECT_EQ(out->type(), CV_16UC3);
  EXPECT_EQ(out->at<cv::Vec3w>(0, 1), cv::Vec3w(4095, 4095, 4095));
  EXPECT_EQ(out->at<cv::Vec3w>(1, 0), cv::Vec3w(1234, 1234, 1234));

  const cv::Mat flat(16, 24, CV_8UC3, cv::Scalar(30, 120, 210));
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", flat, jpeg));
  out = to_bgr({jpeg.data(), jpeg.size(), 24, 16, 0, PixelLayout::kMJPEG, 8});
  ASSERT_TRUE(out) << out.error().describe();
  EXPECT_LE(max_abs_diff(*out, flat), 3.0);
  jpeg.resize(jpeg.size() / 3);  // truncated transfer
  auto bad = to_bgr({jpeg.data(), jpeg.size(), 24, 16, 0, PixelLayout::kMJPEG, 8});
  if (bad) {
    EXPECT_EQ(bad->rows, 16);  // libjpeg may pad a truncated stream; it must at least not crash or resize
  } else {
    EXPECT_EQ(bad.error().code, ErrorCode::kCorrupt);
  }
}

TEST(PixelConvert, V4l2FormatsAndFourcc) {
  int bits = 0;
  EXPECT_EQ(layout_from_v4l2(V4L2_PIX_FMT_YUYV, &bits), PixelLayout::kYUYV);
  EXPECT_EQ(bits, 8);
  EXPECT_EQ(layout_from_v4l2(V4L2_PIX_FMT_Y12, &bits), PixelLayout::kGrey16);
  EXPECT_EQ(bits, 12);
  EXPECT_EQ(layout_from_v4l2(V4L2_PIX_FMT_BGR24, nullptr), PixelLayout::kBGR24);
  EXPECT_FALSE(layout_from_v4l2(V4L2_PIX_FMT_SRGGB10, nullptr));  // raw Bayer: not handled
  EXPECT_EQ(fourcc_from_string("YUYV"), V4L2_PIX_FMT_YUYV);
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_MJPEG), "MJPG");
  EXPECT_FALSE(fourcc_from_string("YUV"));
}

TEST(V4l2Units, ExposureIn100MicrosecondUnits) {
  EXPECT_EQ(v4l2_exposure_units(0.01, 1, 10000), 100);
  EXPECT_EQ(v4l2_exposure_units(1.0 / 30.0, 1, 10000), 333);
  EXPECT_EQ(v4l2_exposure_units(0.00016, 1, 10000), 2);  // 1.6 units rounds to 2
  EXPECT_EQ(v4l2_exposure_units(0.00014, 1, 10000), 1);  // 1.4 rounds to 1
  EXPECT_EQ(v4l2_exposure_units(1e-6, 3, 10000), 3);     // clamped to the control's minimum
  EXPECT_EQ(v4l2_exposure_units(30.0, 1, 5000), 5000);   // and maximum
  EXPECT_EQ(v4l2_exposure_units(std::nan(""), 1, 5000), 1);
  EXPECT_DOUBLE_EQ(v4l2_exposure_s(333), 0.0333);
}

bool any_device(const char* prefix) {
  for (const auto& e : std::filesystem::directory_iterator("/dev"))
    if (e.path().filename().string().rfind(prefix, 0) == 0) return true;
  return false;
}

TEST(CameraBackends, RegisteredByName) {
  BackendRegistry registry;
  register_hardware_backends(registry);
  const auto names = registry.camera_backends();
  const auto has = [&](const char* n) { return std::find(names.begin(), names.end(), n) != names.end(); };
#ifdef VDRIG_HAVE_V4L2
  EXPECT_TRUE(has("v4l2"));
#endif
#ifdef VDRIG_HAVE_LIBCAMERA
  EXPECT_TRUE(has("libcamera"));
#endif
#ifdef VDRIG_HAVE_USB
  EXPECT_TRUE(has("usb-ptp"));
#endif
  EXPECT_FALSE(has("sim"));  // hardware registration only
}

Result<Rig> camera_rig(const nlohmann::json& camera) {
  BackendRegistry registry;
  register_hardware_backends(registry);
  registry.add_stage("none",
                     [](const nlohmann::json&, RigContext&) -> Result<std::unique_ptr<PanTiltStage>> {
                       return std::unique_ptr<PanTiltStage>();
                     },
                     {.check = [](const nlohmann::json& section) -> Result<nlohmann::json> { return section; }});
  return registry.make_rig({{"stage", {{"backend", "none"}}}, {"camera", camera}});
}

TEST(CameraBackends, V4l2RejectsBadSettingsAndCapturesFromARealDevice) {
#ifndef VDRIG_HAVE_V4L2
  GTEST_SKIP() << "built without libv4l2";
#else
  auto bad = camera_rig({{"backend", "v4l2"}, {"pixel_format", "SRGGB"}, {"width", 640}});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bad.error().message.find("pixel_format"), std::string::npos) << bad.error().message;
  EXPECT_NE(bad.error().message.find("both \"width\" and \"height\""), std::string::npos) << bad.error().message;
  auto missing = camera_rig({{"backend", "v4l2"}, {"device", "/dev/video-vdrig-absent"}});
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  if (!any_device("video")) GTEST_SKIP() << "no /dev/video* on this machine";
  auto rig = camera_rig({{"backend", "v4l2"}, {"device", "/dev/video0"}});
  ASSERT_TRUE(rig) << rig.error().describe();
  auto info = rig->camera->info();
  ASSERT_TRUE(info);
  ASSERT_TRUE(rig->camera->set_exposure(0.01, 1.0));
  auto frame = rig->camera->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(frame->image.cols, info->width);
  EXPECT_EQ(frame->image.rows, info->height);
  EXPECT_EQ(frame->image.channels(), 3);
  EXPECT_NEAR(frame->exposure_s, 0.01, 0.01);
#endif
}

TEST(CameraBackends, LibcameraCapturesWhenACameraIsPresent) {
#ifndef VDRIG_HAVE_LIBCAMERA
  GTEST_SKIP() << "built without libcamera";
#else
  auto bad = camera_rig({{"backend", "libcamera"}, {"timeout_s", -1}});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  auto rig = camera_rig({{"backend", "libcamera"}});
  if (!rig && rig.error().code == ErrorCode::kNotFound) GTEST_SKIP() << rig.error().message;
  ASSERT_TRUE(rig) << rig.error().describe();
  ASSERT_TRUE(rig->camera->set_exposure(0.01, 1.0));
  auto frame = rig->camera->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(frame->image.type(), CV_8UC3);
  EXPECT_NEAR(frame->exposure_s, 0.01, 0.002);
#endif
}

// Discovery is checked on every machine where libusb starts: with no still camera attached the backend must say
// kNotFound; with one attached it must find and open it. Only a build without libusb, or a libusb that cannot
// start here (no usbfs, e.g. in a container), skips.
TEST(CameraBackends, UsbPtpDiscovery) {
#ifndef VDRIG_HAVE_USB
  GTEST_SKIP() << "built without libusb (VDRIG_WITH_USB=OFF)";
#else
  auto bad = camera_rig({{"backend", "usb-ptp"}, {"vendor_id", "canon"}});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bad.error().message.find("vendor_id"), std::string::npos);
  auto list = list_usb_still_cameras();
  if (!list && list.error().code == ErrorCode::kUnsupported)
    GTEST_SKIP() << "libusb cannot start here: " << list.error().message;
  ASSERT_TRUE(list) << list.error().describe();
  auto rig = camera_rig({{"backend", "usb-ptp"}});
  if (list->empty()) {
    ASSERT_FALSE(rig) << "no USB still-image camera is attached, yet the usb-ptp backend opened one";
    EXPECT_EQ(rig.error().code, ErrorCode::kNotFound) << rig.error().describe();
    return;
  }
  ASSERT_TRUE(rig) << list->size() << " USB still-image camera(s) attached, but: " << rig.error().describe();
  EXPECT_FALSE(rig->camera->info()->model.empty());
#endif
}

// A photograph from an attached camera: skipped when there is none, or when the camera cannot be triggered over
// PTP (no InitiateCapture: kUnsupported, docs/rig-ptp.md); any other error fails.
TEST(CameraBackends, UsbPtpCapturesFromAnAttachedCamera) {
#ifndef VDRIG_HAVE_USB
  GTEST_SKIP() << "built without libusb (VDRIG_WITH_USB=OFF)";
#else
  auto list = list_usb_still_cameras();
  if (!list && list.error().code == ErrorCode::kUnsupported)
    GTEST_SKIP() << "libusb cannot start here: " << list.error().message;
  ASSERT_TRUE(list) << list.error().describe();
  if (list->empty()) GTEST_SKIP() << "no USB still-image camera attached";
  auto rig = camera_rig({{"backend", "usb-ptp"}});
  ASSERT_TRUE(rig) << rig.error().describe();
  auto frame = rig->camera->capture();
  if (!frame && frame.error().code == ErrorCode::kUnsupported)
    GTEST_SKIP() << "no PTP capture: " << frame.error().describe();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(frame->image.type(), CV_8UC3);
  EXPECT_EQ(frame->image.cols, rig->camera->info()->width);
#endif
}

}  // namespace
}  // namespace vdrig::rig

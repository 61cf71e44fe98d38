// The usb-ptp camera and its PTP layer against an in-process fake camera: a PtpTransport that answers like a USB
// Still Image camera per ISO 15740 (containers split into bulk transfers of at most the reader's size, zero-length
// packets after whole-packet data phases, events on the interrupt pipe, transaction ids checked), holding one JPEG
// of a known pattern. No hardware needed; the real-camera test is in test_camera_backends.cpp.
#include <gtest/gtest.h>

#ifdef VDRIG_HAVE_USB

#include <algorithm>
#include <deque>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "ptp_protocol.hpp"
#include "usb_ptp_camera.hpp"

namespace vdrig::rig {
namespace {
using namespace ptp;

cv::Mat pattern(int w, int h) {
  cv::Mat m(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      m.at<cv::Vec3b>(y, x) =
          cv::Vec3b(uint8_t(30 + x * 190 / w), uint8_t(40 + y * 180 / h), uint8_t(220 - (x + y) / 4));
  cv::rectangle(m, {w / 4, h / 4, w / 3, h / 3}, cv::Scalar(250, 250, 250), cv::FILLED);
  cv::circle(m, {3 * w / 4, h / 2}, h / 6, cv::Scalar(10, 10, 120), cv::FILLED);
  return m;
}

std::vector<uint8_t> jpeg_of(const cv::Mat& m) {
  std::vector<uint8_t> out;
  EXPECT_TRUE(cv::imencode(".jpg", m, out, {cv::IMWRITE_JPEG_QUALITY, 95}));
  return out;
}

/// A PTP camera behind a USB Still Image interface, answering from memory.
class FakeCamera final : public PtpTransport {
 public:
  static constexpr size_t kPacket = 64;  // full-speed bulk packet size: makes every data phase many packets

  FakeCamera() {
    info.manufacturer = "Acme";
    info.model = "FakeCam 1";
    info.serial_number = "0042";
    info.operations = {kGetDeviceInfo, kOpenSession,     kCloseSession,      kGetObjectInfo,      kGetObject,
                       kDeleteObject,  kInitiateCapture, kGetDevicePropDesc, kGetDevicePropValue, kSetDevicePropValue};
    info.events = {kObjectAdded, kCaptureComplete};
    info.properties = {kExposureTime, kExposureIndex};
    info.capture_formats = info.image_formats = {kFormatExifJpeg};
    exposure.code = kExposureTime;
    exposure.data_type = kUint32;
    exposure.writable = true;
    exposure.form = PropDesc::Form::kEnumeration;
    // 0.1 ms units: 1/10000 .. 1 s, plus the bulb sentinel that must never be chosen.
    exposure.values = {1, 10, 40, 80, 125, 250, 500, 1000, 2000, 10000, 0xFFFFFFFF};
    exposure.current = exposure.factory_default = 125;
    iso.code = kExposureIndex;
    iso.data_type = kUint16;
    iso.writable = true;
    iso.form = PropDesc::Form::kEnumeration;
    iso.values = {100, 200, 400, 800, 1600};
    iso.current = iso.factory_default = 100;
    image = pattern(320, 240);
    jpeg = jpeg_of(image);
  }

  // ---- what the camera is ----
  DeviceInfo info;
  PropDesc exposure, iso;
  cv::Mat image;
  std::vector<uint8_t> jpeg;      // what the next capture stores
  bool send_complete = true;      // CaptureComplete after ObjectAdded
  bool split_data_header = true;  // the 12-byte data header in a transfer of its own (some cameras do)

  // ---- injections ----
  std::map<uint16_t, int> busy;        // op -> DeviceBusy answers still to give
  std::map<uint16_t, uint16_t> fail;   // op -> response code to answer instead
  std::optional<uint16_t> corrupt_op;  // this op's response gets `corrupt_how`
  enum class Corruption { kLengthTooShort, kLengthMismatch, kWrongTid, kEventOnBulk } corrupt_how{};
  long disconnect_after_bytes = -1;  // bulk-in bytes delivered before the cable is pulled (-1: never)

  // ---- what happened ----
  std::map<uint16_t, int> commands;  // op -> times received
  std::map<uint32_t, std::vector<uint8_t>> objects;
  std::vector<uint32_t> deleted;
  int bulk_reads = 0;
  bool session_open = false;
  bool unplugged = false;

  Status send(const uint8_t* data, size_t n, int) override {
    if (unplugged) return make_error(ErrorCode::kDisconnected, "fake: unplugged");
    auto c = decode_container(data, n);
    EXPECT_TRUE(c) << c.error().describe();
    if (!c) return Status::ok();
    if (c->type == kCommand) {
      if (c->code == kSetDevicePropValue) {
        pending_ = *c;  // its value follows in a data container
        return Status::ok();
      }
      handle(*c, nullptr);
    } else if (c->type == kData) {
      EXPECT_TRUE(pending_ && pending_->transaction_id == c->transaction_id);
      if (pending_) handle(*pending_, &c->payload);
      pending_.reset();
    } else {
      ADD_FAILURE() << "host sent container type " << c->type;
    }
    return Status::ok();
  }

  Result<size_t> receive(uint8_t* data, size_t max, int) override {
    if (unplugged) return make_error(ErrorCode::kDisconnected, "fake: unplugged");
    if (in_.empty()) return make_error(ErrorCode::kTimeout, "fake: nothing to read");
    EXPECT_EQ(max % kPacket, 0u) << "a bulk read must ask for whole packets";
    ++bulk_reads;
    auto& front = in_.front();
    size_t k = std::min(max, front.size() - offset_);
    if (disconnect_after_bytes >= 0) {
      if (disconnect_after_bytes == 0) {
        unplugged = true;
        return make_error(ErrorCode::kDisconnected, "fake: unplugged mid-transfer");
      }
      k = std::min<size_t>(k, static_cast<size_t>(disconnect_after_bytes));
      disconnect_after_bytes -= static_cast<long>(k);
    }
    std::copy_n(front.begin() + static_cast<ptrdiff_t>(offset_), k, data);
    offset_ += k;
    if (offset_ == front.size()) {
      in_.pop_front();
      offset_ = 0;
    }
    return k;
  }

  Result<std::vector<uint8_t>> receive_event(int) override {
    if (unplugged) return make_error(ErrorCode::kDisconnected, "fake: unplugged");
    if (events_.empty()) return make_error(ErrorCode::kTimeout, "fake: no event");
    auto e = std::move(events_.front());
    events_.pop_front();
    return e;
  }

  void push_event(uint16_t code, std::vector<uint32_t> params) {
    events_.push_back(encode_container(Container{kEvent, code, 0, std::move(params), {}}));
  }
  /// The host reconnects: the cable is back, the camera kept its state (and its session).
  void replug() {
    unplugged = false;
    disconnect_after_bytes = -1;
    in_.clear();
    offset_ = 0;
  }

 private:
  void respond(const Container& cmd, uint16_t code, std::vector<uint32_t> params = {},
               const std::vector<uint8_t>* data = nullptr) {
    if (data) {
      auto bytes = encode_container(Container{kData, cmd.code, cmd.transaction_id, {}, *data});
      if (split_data_header && bytes.size() > kHeaderBytes) {
        in_.emplace_back(bytes.begin(), bytes.begin() + kHeaderBytes);
        in_.emplace_back(bytes.begin() + kHeaderBytes, bytes.end());
      } else {
        in_.push_back(bytes);
      }
      if (bytes.size() % kPacket == 0) in_.emplace_back();  // USB: a whole-packet transfer ends with a ZLP
    }
    auto resp = encode_container(Container{kResponse, code, cmd.transaction_id, std::move(params), {}});
    if (corrupt_op == cmd.code) {
      corrupt_op.reset();
      switch (corrupt_how) {
        case Corruption::kLengthTooShort:
          resp[0] = 8;
          break;
        case Corruption::kLengthMismatch:
          resp[0] = static_cast<uint8_t>(resp.size() + 4);
          break;
        case Corruption::kWrongTid:
          resp[8] ^= 0x5A;
          break;
        case Corruption::kEventOnBulk:
          resp[4] = kEvent;
          break;
      }
    }
    in_.push_back(std::move(resp));
  }

  void handle(const Container& cmd, const std::vector<uint8_t>* data_in) {
    ++commands[cmd.code];
    const auto p = [&](size_t i) { return i < cmd.params.size() ? cmd.params[i] : 0u; };
    // Transaction ids: 0 outside a session, then consecutive from 1 after OpenSession (ISO 15740 9.3.1).
    // CloseSession is taken with any id: a host cleaning up a session left by a crashed run cannot know its count.
    if (cmd.code != kOpenSession && !(cmd.code == kGetDeviceInfo && cmd.transaction_id == 0)) {
      if (!session_open) return respond(cmd, kSessionNotOpen);
      if (cmd.code != kCloseSession && cmd.transaction_id != last_tid_ + 1) return respond(cmd, kInvalidTransactionId);
      last_tid_ = cmd.transaction_id;
    }
    if (std::find(info.operations.begin(), info.operations.end(), cmd.code) == info.operations.end())
      return respond(cmd, kOperationNotSupported);
    if (auto it = busy.find(cmd.code); it != busy.end() && it->second > 0) {
      --it->second;
      return respond(cmd, kDeviceBusy);
    }
    if (auto it = fail.find(cmd.code); it != fail.end()) return respond(cmd, it->second);
    switch (cmd.code) {
      case kGetDeviceInfo: {
        const auto d = info.encode();
        return respond(cmd, kOk, {}, &d);
      }
      case kOpenSession:
        EXPECT_EQ(cmd.transaction_id, 0u);
        if (session_open) return respond(cmd, kSessionAlreadyOpen);
        session_open = true;
        last_tid_ = 0;
        return respond(cmd, kOk);
      case kCloseSession:
        session_open = false;
        return respond(cmd, kOk);
      case kGetDevicePropDesc: {
        const PropDesc* d = p(0) == kExposureTime ? &exposure : p(0) == kExposureIndex ? &iso : nullptr;
        if (!d) return respond(cmd, kDevicePropNotSupported);
        const auto bytes = d->encode();
        return respond(cmd, kOk, {}, &bytes);
      }
      case kSetDevicePropValue: {
        PropDesc* d = p(0) == kExposureTime ? &exposure : p(0) == kExposureIndex ? &iso : nullptr;
        if (!d) return respond(cmd, kDevicePropNotSupported);
        Reader r(data_in->data(), data_in->size());
        const int64_t v = r.value(d->data_type);
        if (r.failed() || r.remaining() != 0) return respond(cmd, kInvalidDevicePropValue);
        if (std::find(d->values.begin(), d->values.end(), v) == d->values.end())
          return respond(cmd, kInvalidDevicePropValue);
        d->current = v;
        return respond(cmd, kOk);
      }
      case kInitiateCapture: {
        const uint32_t handle = 0x1000 + next_object_++;
        objects[handle] = jpeg;
        respond(cmd, kOk);
        push_event(kObjectAdded, {handle});
        if (send_complete) push_event(kCaptureComplete, {cmd.transaction_id});
        return;
      }
      case kGetObjectInfo: {
        auto it = objects.find(p(0));
        if (it == objects.end()) return respond(cmd, kInvalidObjectHandle);
        ObjectInfo oi;
        oi.storage_id = 0x00010001;
        oi.format = kFormatExifJpeg;
        oi.compressed_size = static_cast<uint32_t>(it->second.size());
        oi.width = static_cast<uint32_t>(image.cols);
        oi.height = static_cast<uint32_t>(image.rows);
        oi.bit_depth = 24;
        oi.filename = "IMG_" + std::to_string(it->first) + ".JPG";
        const auto bytes = oi.encode();
        return respond(cmd, kOk, {}, &bytes);
      }
      case kGetObject: {
        auto it = objects.find(p(0));
        if (it == objects.end()) return respond(cmd, kInvalidObjectHandle);
        return respond(cmd, kOk, {}, &it->second);
      }
      case kDeleteObject:
        if (!objects.erase(p(0))) return respond(cmd, kInvalidObjectHandle);
        deleted.push_back(p(0));
        return respond(cmd, kOk);
      default:
        return respond(cmd, kOperationNotSupported);
    }
  }

  std::deque<std::vector<uint8_t>> in_;  // bulk-in transfers queued
  size_t offset_ = 0;
  std::deque<std::vector<uint8_t>> events_;
  std::optional<Container> pending_;
  uint32_t last_tid_ = 0;
  uint32_t next_object_ = 1;
};

/// Lets the camera own "a transport" while the test keeps the fake.
class Link final : public PtpTransport {
 public:
  explicit Link(FakeCamera* cam) : cam_(cam) {}
  Status send(const uint8_t* d, size_t n, int t) override { return cam_->send(d, n, t); }
  Result<size_t> receive(uint8_t* d, size_t m, int t) override { return cam_->receive(d, m, t); }
  Result<std::vector<uint8_t>> receive_event(int t) override { return cam_->receive_event(t); }

 private:
  FakeCamera* cam_;
};

SessionOptions fast_options() {
  SessionOptions o;
  o.timeout_ms = 100;
  o.read_chunk_bytes = 512;  // a 20 kB JPEG then takes ~40 bulk reads
  o.busy_backoff_ms = 1;
  o.busy_backoff_max_ms = 4;
  return o;
}

Result<std::unique_ptr<UsbPtpCamera>> camera_on(FakeCamera& fake, nlohmann::json settings = nlohmann::json::object(),
                                                int* opens = nullptr) {
  settings["capture_timeout_s"] = 0.5;
  settings["complete_grace_s"] = 0.05;
  auto config = UsbPtpConfig::parse(settings);
  if (!config) return config.error();
  return UsbPtpCamera::create_with(
      config.value(),
      [&fake, opens]() -> Result<std::unique_ptr<PtpTransport>> {
        if (opens) ++*opens;
        if (fake.unplugged) return make_error(ErrorCode::kNotFound, "fake: no camera on USB");
        return std::unique_ptr<PtpTransport>(new Link(&fake));
      },
      fast_options());
}

double psnr(const cv::Mat& a, const cv::Mat& b) { return cv::PSNR(a, b); }

TEST(PtpCamera, CaptureRoundTripDecodesThePatternWithTheNearestExposure) {
  FakeCamera fake;
  auto cam = camera_on(fake);
  ASSERT_TRUE(cam) << cam.error().describe();
  auto info = (*cam)->info();
  ASSERT_TRUE(info);
  EXPECT_EQ(info->model, "Acme FakeCam 1");
  EXPECT_DOUBLE_EQ(info->min_exposure_s, 1e-4);  // 1 unit of 0.1 ms
  EXPECT_DOUBLE_EQ(info->max_exposure_s, 1.0);   // 10000 units; the bulb sentinel is not an exposure
  EXPECT_FALSE(info->auto_exposure_on);

  // 7.5 ms lies between 4 ms and 8 ms: 8 ms is nearer (in stops and in ms). Gain 3 at base ISO 100 asks ISO 300:
  // 400 is 0.42 stops off, 200 is 0.58.
  ASSERT_TRUE((*cam)->set_exposure(0.0075, 3.0));
  EXPECT_EQ(fake.exposure.current, 80);
  EXPECT_EQ(fake.iso.current, 400);
  auto frame = (*cam)->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_DOUBLE_EQ(frame->exposure_s, 0.008);
  EXPECT_DOUBLE_EQ(frame->gain, 4.0);
  ASSERT_EQ(frame->image.type(), CV_8UC3);
  ASSERT_EQ(frame->image.size(), fake.image.size());
  EXPECT_GT(psnr(frame->image, fake.image), 35.0);
  EXPECT_LT(cv::norm(frame->image, fake.image, cv::NORM_L1) / double(fake.image.total() * 3), 2.0);
  EXPECT_GT(fake.bulk_reads, 30);      // the JPEG crossed in many bulk transfers
  EXPECT_EQ(fake.deleted.size(), 1u);  // not kept on the card
  EXPECT_TRUE(fake.objects.empty());
  info = (*cam)->info();
  EXPECT_EQ(info->width, 320);
  EXPECT_EQ(info->height, 240);

  // 0.3 s: 0.2 s (0.58 stops) is nearer than 1 s (1.74 stops); gain 1 is ISO 100 again.
  ASSERT_TRUE((*cam)->set_exposure(0.3, 1.0));
  EXPECT_EQ(fake.exposure.current, 2000);
  EXPECT_EQ(fake.iso.current, 100);
  frame = (*cam)->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_DOUBLE_EQ(frame->exposure_s, 0.2);
  EXPECT_EQ(frame->sequence, 1u);
}

TEST(PtpCamera, KeepOnCardAndMissingCaptureCompleteAndSettings) {
  FakeCamera fake;
  fake.send_complete = false;  // some cameras never send CaptureComplete: the grace period ends the wait
  auto cam = camera_on(fake, {{"keep_on_card", true}});
  ASSERT_TRUE(cam) << cam.error().describe();
  auto frame = (*cam)->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_TRUE(fake.deleted.empty());
  EXPECT_EQ(fake.objects.size(), 1u);
  EXPECT_GT(psnr(frame->image, fake.image), 35.0);

  auto bad = UsbPtpConfig::parse(
      {{"vendor_id", "nikon"}, {"index", -1}, {"timeout_s", 0}, {"keep_on_card", 2}, {"exposure", 1}});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  for (const char* key : {"vendor_id", "index", "timeout_s", "keep_on_card", "exposure"})
    EXPECT_NE(bad.error().message.find(key), std::string::npos) << key << " in: " << bad.error().message;
  auto good = UsbPtpConfig::parse({{"vendor_id", "04A9"}, {"product_id", "0x3218"}});
  ASSERT_TRUE(good) << good.error().describe();
  EXPECT_EQ(good->vendor_id, 0x04a9);
  EXPECT_EQ(good->product_id, 0x3218);
}

TEST(PtpSession, DataPhasesSpanManyTransfersAndZeroLengthPacketsAreSkipped) {
  FakeCamera fake;
  PtpSession s(fake, fast_options());
  ASSERT_TRUE(s.open());
  // An object whose data container (12-byte header + payload) is exactly 300 packets: the camera then ends the
  // transfer with a zero-length packet, which must not be taken for the next response.
  std::vector<uint8_t> blob(300 * FakeCamera::kPacket - kHeaderBytes);
  std::mt19937 rng(7);
  for (auto& b : blob) b = static_cast<uint8_t>(rng());
  fake.objects[0x77] = blob;
  const int reads_before = fake.bulk_reads;
  auto got = s.get_object(0x77);
  ASSERT_TRUE(got) << got.error().describe();
  EXPECT_EQ(got.value(), blob);
  EXPECT_GE(fake.bulk_reads - reads_before, 38);  // 19200 bytes in 512-byte reads, plus header and response
  auto again = s.get_object(0x77);                // the ZLP left in the pipe is skipped
  ASSERT_TRUE(again) << again.error().describe();
  EXPECT_EQ(again->size(), blob.size());
  // The same with the data header in the first transfer and reads bigger than the container.
  fake.split_data_header = false;
  SessionOptions big = fast_options();
  big.read_chunk_bytes = 1 << 16;
  PtpSession s2(fake, big);
  ASSERT_TRUE(s.close());
  ASSERT_TRUE(s2.open());
  got = s2.get_object(0x77);
  ASSERT_TRUE(got) << got.error().describe();
  EXPECT_EQ(got.value(), blob);
}

TEST(PtpSession, DeviceBusyIsRetriedThenGivesUpNamingIt) {
  FakeCamera fake;
  PtpSession s(fake, fast_options());
  ASSERT_TRUE(s.open());
  fake.busy[kInitiateCapture] = 3;
  auto handles = s.capture(500, 50);
  ASSERT_TRUE(handles) << handles.error().describe();
  EXPECT_EQ(handles->size(), 1u);
  EXPECT_EQ(fake.commands[kInitiateCapture], 4);  // three busy answers, then the capture

  SessionOptions few = fast_options();
  few.busy_retries = 2;
  PtpSession s2(fake, few);
  ASSERT_TRUE(s.close());
  ASSERT_TRUE(s2.open());
  fake.busy[kGetObjectInfo] = 100;
  auto info = s2.get_object_info(handles->front());
  ASSERT_FALSE(info);
  EXPECT_EQ(info.error().code, ErrorCode::kDevice);
  EXPECT_NE(info.error().message.find("DeviceBusy (0x2019)"), std::string::npos) << info.error().message;
  EXPECT_EQ(fake.commands[kGetObjectInfo], 3);
}

TEST(PtpSession, ErrorResponsesAreNamed) {
  FakeCamera fake;
  PtpSession s(fake, fast_options());
  ASSERT_TRUE(s.open());
  auto obj = s.get_object(0xdead);
  ASSERT_FALSE(obj);
  EXPECT_EQ(obj.error().code, ErrorCode::kDevice);
  EXPECT_NE(obj.error().message.find("GetObject (0x1009)"), std::string::npos) << obj.error().message;
  EXPECT_NE(obj.error().message.find("InvalidObjectHandle (0x2009)"), std::string::npos) << obj.error().message;
  fake.fail[kDeleteObject] = kAccessDenied;
  const Status del = s.delete_object(1);
  ASSERT_FALSE(del);
  EXPECT_NE(del.error().message.find("AccessDenied"), std::string::npos);
  auto desc = s.get_prop_desc(0x5003);  // ImageSize: the fake does not describe it
  ASSERT_FALSE(desc);
  EXPECT_EQ(desc.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(desc.error().message.find("DevicePropNotSupported"), std::string::npos);
  const Status bad_value = s.set_prop_value(kExposureTime, kUint32, 33);  // not in the enumeration
  ASSERT_FALSE(bad_value);
  EXPECT_NE(bad_value.error().message.find("InvalidDevicePropValue"), std::string::npos);
  // The session is still in step after all those errors.
  auto info = s.get_device_info();
  ASSERT_TRUE(info) << info.error().describe();
  EXPECT_EQ(info->serial_number, "0042");
  EXPECT_TRUE(info->supports_operation(kInitiateCapture));

  // A camera still holding a session from a crashed run: SessionAlreadyOpen is closed and reopened.
  PtpSession again(fake, fast_options());
  ASSERT_TRUE(again.open());
  EXPECT_TRUE(again.get_device_info());
  EXPECT_TRUE(again.get_prop_desc(kExposureTime));
}

TEST(PtpSession, CorruptContainersAreKCorrupt) {
  using C = FakeCamera::Corruption;
  for (C how : {C::kLengthTooShort, C::kLengthMismatch, C::kWrongTid, C::kEventOnBulk}) {
    FakeCamera fake;
    PtpSession s(fake, fast_options());
    ASSERT_TRUE(s.open());
    fake.corrupt_op = kGetDevicePropDesc;
    fake.corrupt_how = how;
    auto d = s.get_prop_desc(kExposureTime);
    ASSERT_FALSE(d) << "corruption " << int(how);
    EXPECT_EQ(d.error().code, ErrorCode::kCorrupt) << d.error().describe();
  }
  // Containers and datasets cut anywhere are errors, never crashes or reads out of bounds (ASan watches in CI).
  FakeCamera fake;
  const std::vector<std::vector<uint8_t>> datasets = {fake.info.encode(), fake.exposure.encode(), fake.iso.encode()};
  for (size_t cut = 0; cut < datasets[0].size(); ++cut) {
    std::vector<uint8_t> part(datasets[0].begin(), datasets[0].begin() + static_cast<ptrdiff_t>(cut));
    EXPECT_EQ(DeviceInfo::decode(part).error().code, ErrorCode::kCorrupt) << cut;
  }
  for (size_t k = 1; k < 3; ++k)
    for (size_t cut = 0; cut < datasets[k].size(); ++cut) {
      std::vector<uint8_t> part(datasets[k].begin(), datasets[k].begin() + static_cast<ptrdiff_t>(cut));
      EXPECT_FALSE(PropDesc::decode(part)) << k << " " << cut;
    }
  auto ok = DeviceInfo::decode(datasets[0]);
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->model, "FakeCam 1");
  EXPECT_EQ(ok->operations, fake.info.operations);
  // A garbage array count must not allocate gigabytes before failing.
  std::vector<uint8_t> huge = {0x64, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff};
  EXPECT_EQ(DeviceInfo::decode(huge).error().code, ErrorCode::kCorrupt);
  const auto cmd = encode_container(Container{kResponse, kOk, 5, {1, 2, 3, 4, 5}, {}});
  EXPECT_TRUE(decode_container(cmd.data(), cmd.size()));
  EXPECT_FALSE(decode_container(cmd.data(), cmd.size() - 2));  // length field disagrees, and not whole params
  auto six = encode_container(Container{kResponse, kOk, 5, {1, 2, 3, 4, 5, 6}, {}});
  EXPECT_EQ(decode_container(six.data(), six.size()).error().code, ErrorCode::kCorrupt);
}

TEST(PtpCamera, DisconnectMidTransferIsKDisconnectedAndTheNextCallReconnects) {
  FakeCamera fake;
  int opens = 0;
  auto cam = camera_on(fake, nlohmann::json::object(), &opens);
  ASSERT_TRUE(cam) << cam.error().describe();
  ASSERT_TRUE((*cam)->set_exposure(0.025, 1.0));
  EXPECT_EQ(fake.exposure.current, 250);
  fake.disconnect_after_bytes = 600;  // during the object's data phase (after the ObjectInfo)
  auto frame = (*cam)->capture();
  ASSERT_FALSE(frame);
  EXPECT_EQ(frame.error().code, ErrorCode::kDisconnected) << frame.error().describe();
  // Still unplugged: the reopen fails cleanly.
  auto still = (*cam)->capture();
  ASSERT_FALSE(still);
  EXPECT_EQ(still.error().code, ErrorCode::kNotFound);
  // Plugged back in: the camera kept its session (SessionAlreadyOpen) and the exposure is applied again.
  fake.replug();
  fake.exposure.current = 125;  // and forgot the exposure
  frame = (*cam)->capture();
  ASSERT_TRUE(frame) << frame.error().describe();
  EXPECT_EQ(fake.exposure.current, 250);
  EXPECT_DOUBLE_EQ(frame->exposure_s, 0.025);
  EXPECT_GT(psnr(frame->image, fake.image), 35.0);
  EXPECT_EQ(opens, 3);
}

TEST(PtpCamera, CameraWithoutInitiateCaptureIsUnsupported) {
  FakeCamera fake;
  std::erase(fake.info.operations, uint16_t(kInitiateCapture));
  auto cam = camera_on(fake);
  ASSERT_TRUE(cam) << cam.error().describe();
  auto frame = (*cam)->capture();
  ASSERT_FALSE(frame);
  EXPECT_EQ(frame.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(frame.error().message.find("InitiateCapture"), std::string::npos) << frame.error().message;
  EXPECT_EQ(fake.commands[kInitiateCapture], 0);

  // A camera in an automatic mode reports ExposureTime read-only: set_exposure says so instead of pretending.
  FakeCamera autocam;
  autocam.exposure.writable = false;
  auto cam2 = camera_on(autocam);
  ASSERT_TRUE(cam2);
  EXPECT_TRUE((*cam2)->info()->auto_exposure_on);
  const Status s = (*cam2)->set_exposure(0.01, 1.0);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(s.error().message.find("read-only"), std::string::npos);
}

TEST(PtpProps, NearestInStopsForEnumerationsAndRanges) {
  PropDesc e;
  e.form = PropDesc::Form::kEnumeration;
  e.data_type = kUint32;
  e.values = {0, 10, 40, 80, 0xFFFFFFFF};
  EXPECT_EQ(e.nearest(57), 80);   // in stops 80 is nearer (0.49 vs 0.51) though 40 is nearer in units
  EXPECT_EQ(e.nearest(1e9), 80);  // bulb (0xFFFFFFFF) and auto (0) are never chosen
  EXPECT_EQ(e.nearest(1), 10);
  EXPECT_FALSE(e.nearest(-1));
  PropDesc r;
  r.form = PropDesc::Form::kRange;
  r.data_type = kUint16;
  r.min = 50;
  r.max = 3200;
  r.step = 50;
  EXPECT_EQ(r.nearest(130), 150);  // 100 is 0.38 stops off, 150 is 0.21
  EXPECT_EQ(r.nearest(10), 50);    // clamped to the range
  EXPECT_EQ(r.nearest(1e6), 3200);
  EXPECT_EQ(r.nearest(3190), 3200);
}

}  // namespace
}  // namespace vdrig::rig

#else
TEST(Ptp, NotBuilt) { GTEST_SKIP() << "built without libusb (VDRIG_WITH_USB=OFF)"; }
#endif

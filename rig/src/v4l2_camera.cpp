#include "v4l2_camera.hpp"

#include <fcntl.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <sys/mman.h>
#include <sys/select.h>
#include <time.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <vector>

#include "backends.hpp"
#include "pixel_convert.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"

namespace vdrig::rig {
namespace {

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = v4l2_ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

bool gone(int err) { return err == ENODEV || err == ENXIO || err == EIO; }

int64_t ns_of(const timespec& t) { return static_cast<int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec; }

}  // namespace

Result<V4l2CameraConfig> V4l2CameraConfig::parse(const nlohmann::json& settings) {
  Settings s(settings, "camera v4l2", {"backend"});
  V4l2CameraConfig c;
  c.device = s.string("device", c.device);
  c.width = static_cast<int>(s.integer("width", 0, 0, 16384));
  c.height = static_cast<int>(s.integer("height", 0, 0, 16384));
  const std::string fmt = s.string("pixel_format", "YUYV");
  const auto fourcc = fourcc_from_string(fmt);
  if (!fourcc)
    s.fail("\"pixel_format\" must be a four-character code such as \"YUYV\", got \"" + fmt + "\"");
  else if (!layout_from_v4l2(*fourcc, nullptr))
    s.fail("\"pixel_format\" \"" + fmt +
           "\" cannot be converted to BGR (supported: YUYV UYVY NV12 BGR3 RGB3 XR24 "
           "BGR4 GREY Y10 Y12 Y16 MJPG JPEG)");
  c.fourcc = fourcc.value_or(0);
  c.discard_frames = static_cast<int>(s.integer("discard_frames", 2, 0, 30));
  c.buffers = static_cast<int>(s.integer("buffers", 4, 2, 32));
  c.timeout_s = s.number("timeout_s", 2.0, 0.01, 600.0);
  c.gain_control_per_unit = s.number("gain_control_per_unit", 1.0, 1e-6, 1e6);
  if ((c.width == 0) != (c.height == 0)) s.fail("give both \"width\" and \"height\" or neither");
  s.reject_unknown(
      {"device", "width", "height", "pixel_format", "discard_frames", "buffers", "timeout_s", "gain_control_per_unit"});
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

nlohmann::json V4l2CameraConfig::effective() const {
  std::string pixel_format;
  for (int i = 0; i < 4; ++i) pixel_format += static_cast<char>((fourcc >> (8 * i)) & 0xff);
  return {{"backend", "v4l2"},
          {"device", device},
          {"width", width},
          {"height", height},
          {"pixel_format", pixel_format},
          {"discard_frames", discard_frames},
          {"buffers", buffers},
          {"timeout_s", timeout_s},
          {"gain_control_per_unit", gain_control_per_unit}};
}

Result<std::unique_ptr<Camera>> V4l2Camera::create(const nlohmann::json& settings) {
  auto config = V4l2CameraConfig::parse(settings);
  if (!config) return config.error();
  std::unique_ptr<V4l2Camera> cam(new V4l2Camera(std::move(config.value())));
  VDRIG_TRY(cam->open());
  return std::unique_ptr<Camera>(std::move(cam));
}

V4l2Camera::~V4l2Camera() { close(); }

void V4l2Camera::close() {
  if (fd_ >= 0) v4l2_close(fd_);
  fd_ = -1;
}

Error V4l2Camera::errno_error(const std::string& what, int err) {
  if (gone(err)) {
    close();  // reopened on the next call
    return make_error(ErrorCode::kDisconnected,
                      "v4l2 " + config_.device + ": " + what + ": " + std::strerror(err) + " (unplugged?)");
  }
  return make_error(err == ETIMEDOUT ? ErrorCode::kTimeout : ErrorCode::kDevice,
                    "v4l2 " + config_.device + ": " + what + ": " + std::strerror(err));
}

Status V4l2Camera::open() {
  if (fd_ >= 0) return Status::ok();
  // libv4l2 wraps the fd: format emulation and per-driver fixes for the many cameras with quirky UVC firmware.
  fd_ = v4l2_open(config_.device.c_str(), O_RDWR | O_NONBLOCK);
  if (fd_ < 0) {
    const int err = errno;
    return make_error(err == ENOENT   ? ErrorCode::kNotFound
                      : err == ENODEV ? ErrorCode::kDisconnected
                                      : ErrorCode::kDevice,
                      "v4l2: cannot open " + config_.device + ": " + std::strerror(err));
  }
  v4l2_capability cap{};
  if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0) return errno_error("VIDIOC_QUERYCAP", errno);
  const uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE) || !(caps & V4L2_CAP_STREAMING)) {
    close();
    return make_error(ErrorCode::kUnsupported,
                      "v4l2: " + config_.device + " is not a streaming capture device (a metadata node?)");
  }
  info_.model = reinterpret_cast<const char*>(cap.card);

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_G_FMT, &fmt) != 0) return errno_error("VIDIOC_G_FMT", errno);
  if (config_.width > 0) {
    fmt.fmt.pix.width = static_cast<uint32_t>(config_.width);
    fmt.fmt.pix.height = static_cast<uint32_t>(config_.height);
  }
  fmt.fmt.pix.pixelformat = config_.fourcc;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd_, VIDIOC_S_FMT, &fmt) != 0) return errno_error("VIDIOC_S_FMT", errno);
  // The driver may adjust anything; what it returns is what we get.
  int bits = 8;
  if (!layout_from_v4l2(fmt.fmt.pix.pixelformat, &bits)) {
    const std::string got = fourcc_to_string(fmt.fmt.pix.pixelformat);
    close();
    return make_error(ErrorCode::kUnsupported, "v4l2: " + config_.device + " delivers " + got + " instead of " +
                                                   fourcc_to_string(config_.fourcc) + ", which we cannot convert");
  }
  if (config_.width > 0 &&
      (static_cast<int>(fmt.fmt.pix.width) != config_.width || static_cast<int>(fmt.fmt.pix.height) != config_.height))
    log::get("rig")->warn("v4l2 {}: asked for {}x{}, the driver gives {}x{}", config_.device, config_.width,
                          config_.height, fmt.fmt.pix.width, fmt.fmt.pix.height);
  fourcc_ = fmt.fmt.pix.pixelformat;
  bytesperline_ = static_cast<int>(fmt.fmt.pix.bytesperline);
  info_.width = static_cast<int>(fmt.fmt.pix.width);
  info_.height = static_cast<int>(fmt.fmt.pix.height);
  info_.bits = bits;

  // Manual exposure: a bracket needs every frame at the exposure asked for.
  const auto set_ctrl = [&](uint32_t id, int32_t value, const char* name) {
    v4l2_control c{id, value};
    if (xioctl(fd_, VIDIOC_S_CTRL, &c) != 0 && errno != EINVAL)  // EINVAL: the camera has no such control
      log::get("rig")->warn("v4l2 {}: cannot set {}: {}", config_.device, name, std::strerror(errno));
  };
  set_ctrl(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "manual exposure");
  set_ctrl(V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0, "exposure priority off");  // else UVC cams drop the frame rate
  set_ctrl(V4L2_CID_AUTOGAIN, 0, "auto gain off");
  v4l2_control ae{V4L2_CID_EXPOSURE_AUTO, 0};
  info_.auto_exposure_on = xioctl(fd_, VIDIOC_G_CTRL, &ae) == 0 && ae.value != V4L2_EXPOSURE_MANUAL;

  v4l2_queryctrl q{};
  q.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  if (xioctl(fd_, VIDIOC_QUERYCTRL, &q) != 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) {
    close();
    return make_error(ErrorCode::kUnsupported, "v4l2: " + config_.device + " has no absolute exposure control");
  }
  exposure_min_ = std::max(1, q.minimum);
  exposure_max_ = q.maximum;
  info_.min_exposure_s = v4l2_exposure_s(exposure_min_);
  info_.max_exposure_s = v4l2_exposure_s(exposure_max_);
  has_gain_ = false;
  for (uint32_t id : {static_cast<uint32_t>(V4L2_CID_GAIN), static_cast<uint32_t>(V4L2_CID_ANALOGUE_GAIN)}) {
    v4l2_queryctrl g{};
    g.id = id;
    if (xioctl(fd_, VIDIOC_QUERYCTRL, &g) == 0 && !(g.flags & V4L2_CTRL_FLAG_DISABLED)) {
      has_gain_ = true;
      gain_cid_ = id;
      gain_min_ = g.minimum;
      gain_max_ = g.maximum;
      break;
    }
  }
  log::get("rig")->info("v4l2 {}: {} {}x{} {} exposure {}..{} s", config_.device, info_.model, info_.width,
                        info_.height, fourcc_to_string(fourcc_), info_.min_exposure_s, info_.max_exposure_s);
  return apply_exposure();
}

Result<CameraInfo> V4l2Camera::info() {
  VDRIG_TRY(open());
  return info_;
}

Status V4l2Camera::set_exposure(double exposure_s, double gain) {
  if (!(exposure_s > 0.0) || !(gain > 0.0))
    return make_error(ErrorCode::kInvalidArgument, "v4l2: exposure and gain must be positive");
  exposure_s_ = exposure_s;
  gain_ = gain;
  VDRIG_TRY(open());
  return apply_exposure();
}

Status V4l2Camera::apply_exposure() {
  v4l2_control c{V4L2_CID_EXPOSURE_ABSOLUTE, v4l2_exposure_units(exposure_s_, exposure_min_, exposure_max_)};
  if (xioctl(fd_, VIDIOC_S_CTRL, &c) != 0) return errno_error("setting exposure", errno);
  if (xioctl(fd_, VIDIOC_G_CTRL, &c) != 0) return errno_error("reading exposure", errno);
  used_exposure_s_ = v4l2_exposure_s(c.value);
  if (std::abs(used_exposure_s_ - exposure_s_) > 0.01 * exposure_s_)
    log::get("rig")->debug("v4l2 {}: exposure {} s taken as {} s", config_.device, exposure_s_, used_exposure_s_);
  used_gain_ = 1.0;
  if (has_gain_) {
    const double want = std::round(gain_ * config_.gain_control_per_unit);
    v4l2_control g{gain_cid_, static_cast<int32_t>(std::clamp(want, double(gain_min_), double(gain_max_)))};
    if (xioctl(fd_, VIDIOC_S_CTRL, &g) != 0) return errno_error("setting gain", errno);
    if (xioctl(fd_, VIDIOC_G_CTRL, &g) != 0) return errno_error("reading gain", errno);
    used_gain_ = g.value / config_.gain_control_per_unit;
  } else if (gain_ != 1.0) {
    log::get("rig")->warn("v4l2 {}: no gain control; gain {} ignored", config_.device, gain_);
  }
  return Status::ok();
}

Result<cv::Mat> V4l2Camera::grab(int64_t* timestamp_ns, uint32_t* sequence) {
  struct Mapping {
    void* start = MAP_FAILED;
    size_t length = 0;
  };
  std::vector<Mapping> maps;
  bool streaming = false;
  // Releases buffers whatever the exit path; skipped once the fd is gone.
  const auto cleanup = [&] {
    if (fd_ < 0) return;
    if (streaming) {
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      xioctl(fd_, VIDIOC_STREAMOFF, &type);
    }
    for (auto& m : maps)
      if (m.start != MAP_FAILED) v4l2_munmap(m.start, m.length);
    v4l2_requestbuffers none{};
    none.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    none.memory = V4L2_MEMORY_MMAP;
    xioctl(fd_, VIDIOC_REQBUFS, &none);
  };
  const auto fail = [&](const std::string& what, int err) -> Error {
    cleanup();
    return errno_error(what, err);
  };

  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(config_.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_REQBUFS, &req) != 0) return fail("VIDIOC_REQBUFS", errno);
  if (req.count < 2) return fail("too few buffers", ENOMEM);
  maps.resize(req.count);
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (xioctl(fd_, VIDIOC_QUERYBUF, &b) != 0) return fail("VIDIOC_QUERYBUF", errno);
    maps[i].length = b.length;
    maps[i].start = v4l2_mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, b.m.offset);
    if (maps[i].start == MAP_FAILED) return fail("mmap", errno);
    if (xioctl(fd_, VIDIOC_QBUF, &b) != 0) return fail("VIDIOC_QBUF", errno);
  }
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_STREAMON, &type) != 0) return fail("VIDIOC_STREAMON", errno);
  streaming = true;

  const double wait_s = config_.timeout_s + used_exposure_s_;
  for (int n = 0; n <= config_.discard_frames; ++n) {
    fd_set fds;
    FD_ZERO(&fds);
    FD_SET(fd_, &fds);
    timeval tv{static_cast<time_t>(wait_s), static_cast<suseconds_t>((wait_s - std::floor(wait_s)) * 1e6)};
    const int r = select(fd_ + 1, &fds, nullptr, nullptr, &tv);
    if (r == -1 && errno == EINTR) {
      --n;
      continue;
    }
    if (r == -1) return fail("select", errno);
    if (r == 0) {
      cleanup();
      return make_error(ErrorCode::kTimeout,
                        "v4l2 " + config_.device + ": no frame within " + std::to_string(wait_s) + " s");
    }
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_DQBUF, &b) != 0) {
      if (errno == EAGAIN) {
        --n;
        continue;
      }
      return fail("VIDIOC_DQBUF", errno);
    }
    if (n < config_.discard_frames || (b.flags & V4L2_BUF_FLAG_ERROR)) {
      if (b.flags & V4L2_BUF_FLAG_ERROR) --n;  // a corrupted frame does not count
      if (xioctl(fd_, VIDIOC_QBUF, &b) != 0) return fail("VIDIOC_QBUF", errno);
      continue;
    }
    int bits = 8;
    const PixelBuffer pb{static_cast<const uint8_t*>(maps[b.index].start),
                         b.bytesused,
                         info_.width,
                         info_.height,
                         static_cast<size_t>(bytesperline_),
                         *layout_from_v4l2(fourcc_, &bits),
                         bits};
    auto image = to_bgr(pb);
    // Kernel timestamps are CLOCK_MONOTONIC; Frame wants CLOCK_REALTIME at exposure start. Most UVC drivers stamp
    // the end of the frame (TSTAMP_SRC_EOF), so the exposure is taken off unless the driver says start-of-exposure.
    timespec mono, real;
    clock_gettime(CLOCK_MONOTONIC, &mono);
    clock_gettime(CLOCK_REALTIME, &real);
    int64_t stamp = ns_of(real);
    if ((b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
      const int64_t buf_ns = static_cast<int64_t>(b.timestamp.tv_sec) * 1000000000LL + b.timestamp.tv_usec * 1000LL;
      stamp = ns_of(real) - (ns_of(mono) - buf_ns);
      if ((b.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) != V4L2_BUF_FLAG_TSTAMP_SRC_SOE)
        stamp -= static_cast<int64_t>(used_exposure_s_ * 1e9);
    }
    *timestamp_ns = stamp;
    *sequence = b.sequence;
    cleanup();
    return image;
  }
  cleanup();
  return make_error(ErrorCode::kInternal, "v4l2: capture loop ended without a frame");
}

Result<Frame> V4l2Camera::capture() {
  VDRIG_TRY(open());
  Frame f;
  uint32_t seq = 0;
  auto image = grab(&f.timestamp_ns, &seq);
  if (!image) return image.error();
  f.image = std::move(image.value());
  f.exposure_s = used_exposure_s_;
  f.gain = used_gain_;
  f.bits = info_.bits;
  // Streaming restarts per capture, so the driver's counter restarts too: count captures ourselves.
  f.sequence = captures_++;
  return f;
}

void register_v4l2_backend(BackendRegistry& registry) {
  registry.add_camera("v4l2", [](const nlohmann::json& settings, RigContext&) { return V4l2Camera::create(settings); },
                      {.check = settings_check(V4l2CameraConfig::parse)});
}

}  // namespace vdrig::rig

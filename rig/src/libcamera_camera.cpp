#include "libcamera_camera.hpp"

#include <sys/mman.h>
#include <time.h>

#include <libcamera/libcamera.h>
#include <chrono>
#include <condition_variable>
#include <mutex>

#include "backends.hpp"
#include "pixel_convert.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"

namespace vdrig::rig {

namespace lc = libcamera;

struct LibcameraCamera::Impl {
  std::unique_ptr<lc::CameraManager> manager;
  std::shared_ptr<lc::Camera> camera;
  std::unique_ptr<lc::CameraConfiguration> config;
  std::unique_ptr<lc::FrameBufferAllocator> allocator;
  lc::Stream* stream = nullptr;
  PixelLayout layout = PixelLayout::kBGR24;
  double timeout_s = 5.0;
  CameraInfo info;
  double exposure_s = 0.01, gain = 1.0;
  uint64_t captures = 0;

  std::mutex mutex;
  std::condition_variable done_cv;
  lc::Request* completed = nullptr;
  bool disconnected = false;

  // Called from libcamera's own thread.
  void on_complete(lc::Request* request) {
    std::lock_guard lock(mutex);
    completed = request;
    done_cv.notify_all();
  }
  void on_disconnect() {
    std::lock_guard lock(mutex);
    disconnected = true;
    done_cv.notify_all();
  }

  ~Impl() {
    if (camera) {
      camera->requestCompleted.disconnect(this);
      camera->disconnected.disconnect(this);
      if (stream && allocator) allocator->free(stream);
      allocator.reset();
      camera->release();
      camera.reset();
    }
    if (manager) manager->stop();
  }
};

namespace {

// libcamera names formats after DRM, whose fourccs describe a little-endian word: RGB888 is B,G,R in memory
// (OpenCV's BGR) and BGR888 is R,G,B. Easy to get backwards.
std::optional<PixelLayout> layout_of(const lc::PixelFormat& f) {
  if (f == lc::formats::RGB888) return PixelLayout::kBGR24;
  if (f == lc::formats::BGR888) return PixelLayout::kRGB24;
  if (f == lc::formats::XRGB8888 || f == lc::formats::ARGB8888) return PixelLayout::kBGRX32;
  if (f == lc::formats::XBGR8888 || f == lc::formats::ABGR8888) return PixelLayout::kRGBX32;
  if (f == lc::formats::YUYV) return PixelLayout::kYUYV;
  if (f == lc::formats::UYVY) return PixelLayout::kUYVY;
  if (f == lc::formats::NV12) return PixelLayout::kNV12;
  return std::nullopt;
}

}  // namespace

Result<std::vector<std::string>> list_libcamera_cameras() {
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);  // a listing, not a debugging session (unless asked for)
  lc::CameraManager manager;
  if (const int r = manager.start(); r != 0)
    return make_error(ErrorCode::kDevice, "libcamera: camera manager did not start: " + std::string(strerror(-r)));
  std::vector<std::string> out;
  for (const auto& camera : manager.cameras()) {
    std::string entry = camera->id();
    if (const auto model = camera->properties().get(lc::properties::Model)) entry += " (" + std::string(*model) + ")";
    out.push_back(std::move(entry));
  }
  manager.stop();
  return out;
}

LibcameraCamera::LibcameraCamera(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LibcameraCamera::~LibcameraCamera() = default;

Result<LibcameraConfig> LibcameraConfig::parse(const nlohmann::json& settings) {
  Settings s(settings, "camera libcamera", {"backend"});
  LibcameraConfig c;
  c.camera_id = s.string("camera_id", "");
  c.width = static_cast<int>(s.integer("width", 0, 0, 16384));
  c.height = static_cast<int>(s.integer("height", 0, 0, 16384));
  c.timeout_s = s.number("timeout_s", 5.0, 0.1, 600.0);
  if ((c.width == 0) != (c.height == 0)) s.fail("give both \"width\" and \"height\" or neither");
  s.reject_unknown({"camera_id", "width", "height", "timeout_s"});
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

nlohmann::json LibcameraConfig::effective() const {
  return {{"backend", "libcamera"},
          {"camera_id", camera_id.empty() ? "first camera" : camera_id},
          {"width", width},
          {"height", height},
          {"timeout_s", timeout_s}};
}

Result<std::unique_ptr<Camera>> LibcameraCamera::create(const LibcameraConfig& config) {
  const std::string& id = config.camera_id;
  const int width = config.width;
  const int height = config.height;
  const double timeout_s = config.timeout_s;

  auto impl = std::make_unique<Impl>();
  impl->timeout_s = timeout_s;
  impl->manager = std::make_unique<lc::CameraManager>();
  if (const int r = impl->manager->start(); r != 0)
    return make_error(ErrorCode::kDevice, "libcamera: camera manager did not start: " + std::string(strerror(-r)));
  const auto cameras = impl->manager->cameras();
  if (cameras.empty()) return make_error(ErrorCode::kNotFound, "libcamera: no camera found");
  impl->camera = id.empty() ? cameras.front() : impl->manager->get(id);
  if (!impl->camera) {
    std::string known;
    for (const auto& c : cameras) known += (known.empty() ? "" : ", ") + c->id();
    return make_error(ErrorCode::kNotFound, "libcamera: no camera \"" + id + "\"; found: " + known);
  }
  if (impl->camera->acquire() != 0)
    return make_error(ErrorCode::kDevice, "libcamera: camera " + impl->camera->id() + " is in use by another process");
  impl->camera->requestCompleted.connect(impl.get(), &Impl::on_complete);
  impl->camera->disconnected.connect(impl.get(), &Impl::on_disconnect);

  impl->config = impl->camera->generateConfiguration({lc::StreamRole::StillCapture});
  if (!impl->config) return make_error(ErrorCode::kUnsupported, "libcamera: no still-capture configuration");
  lc::StreamConfiguration& sc = impl->config->at(0);
  sc.pixelFormat = lc::formats::RGB888;
  sc.bufferCount = 1;
  if (width > 0) sc.size = lc::Size(static_cast<unsigned>(width), static_cast<unsigned>(height));
  switch (impl->config->validate()) {
    case lc::CameraConfiguration::Invalid:
      return make_error(ErrorCode::kUnsupported, "libcamera: still configuration rejected");
    case lc::CameraConfiguration::Adjusted:
      log::get("rig")->warn("libcamera: configuration adjusted to {}", sc.toString());
      break;
    case lc::CameraConfiguration::Valid:
      break;
  }
  const auto layout = layout_of(sc.pixelFormat);
  if (!layout)
    return make_error(ErrorCode::kUnsupported,
                      "libcamera: pipeline delivers " + sc.pixelFormat.toString() + ", which we cannot convert to BGR");
  impl->layout = *layout;
  if (impl->camera->configure(impl->config.get()) != 0)
    return make_error(ErrorCode::kDevice, "libcamera: configure failed");
  impl->stream = sc.stream();
  impl->allocator = std::make_unique<lc::FrameBufferAllocator>(impl->camera);
  if (impl->allocator->allocate(impl->stream) < 1)
    return make_error(ErrorCode::kDevice, "libcamera: cannot allocate frame buffers");

  CameraInfo& info = impl->info;
  info.model = impl->camera->id();
  info.width = static_cast<int>(sc.size.width);
  info.height = static_cast<int>(sc.size.height);
  info.bits = 8;
  const auto& ctrls = impl->camera->controls();
  if (auto it = ctrls.find(&lc::controls::ExposureTime); it != ctrls.end()) {
    info.min_exposure_s = std::max(1, it->second.min().get<int32_t>()) * 1e-6;
    info.max_exposure_s = it->second.max().get<int32_t>() * 1e-6;
  }
  info.auto_exposure_on = false;  // every request carries AeEnable = false
  log::get("rig")->info("libcamera: {} {}", info.model, sc.toString());
  return std::unique_ptr<Camera>(new LibcameraCamera(std::move(impl)));
}

Result<CameraInfo> LibcameraCamera::info() { return impl_->info; }

Status LibcameraCamera::set_exposure(double exposure_s, double gain) {
  if (!(exposure_s > 0.0) || !(gain > 0.0))
    return make_error(ErrorCode::kInvalidArgument, "libcamera: exposure and gain must be positive");
  impl_->exposure_s = exposure_s;
  impl_->gain = gain;
  return Status::ok();
}

Result<Frame> LibcameraCamera::capture() {
  Impl& d = *impl_;
  {
    std::lock_guard lock(d.mutex);
    if (d.disconnected) return make_error(ErrorCode::kDisconnected, "libcamera: camera " + d.info.model + " went away");
    d.completed = nullptr;
  }
  std::unique_ptr<lc::Request> request = d.camera->createRequest();
  if (!request) return make_error(ErrorCode::kDevice, "libcamera: cannot create a request");
  lc::FrameBuffer* buffer = d.allocator->buffers(d.stream).front().get();
  if (request->addBuffer(d.stream, buffer) != 0) return make_error(ErrorCode::kDevice, "libcamera: addBuffer failed");
  const auto us = static_cast<int32_t>(std::clamp(d.exposure_s, d.info.min_exposure_s, d.info.max_exposure_s) * 1e6);
  // Controls in the start() list apply from the first frame; repeating them in the request keeps them there.
  lc::ControlList start_controls(lc::controls::controls);
  start_controls.set(lc::controls::AeEnable, false);
  start_controls.set(lc::controls::ExposureTime, us);
  start_controls.set(lc::controls::AnalogueGain, static_cast<float>(d.gain));
  request->controls().set(lc::controls::AeEnable, false);
  request->controls().set(lc::controls::ExposureTime, us);
  request->controls().set(lc::controls::AnalogueGain, static_cast<float>(d.gain));
  if (d.camera->start(&start_controls) != 0) return make_error(ErrorCode::kDevice, "libcamera: start failed");
  const auto stop = [&] { d.camera->stop(); };
  if (d.camera->queueRequest(request.get()) != 0) {
    stop();
    return make_error(ErrorCode::kDevice, "libcamera: queueRequest failed");
  }
  {
    std::unique_lock lock(d.mutex);
    const bool ok = d.done_cv.wait_for(lock, std::chrono::duration<double>(d.timeout_s + d.exposure_s),
                                       [&] { return d.completed != nullptr || d.disconnected; });
    if (d.disconnected) {
      lock.unlock();
      stop();
      return make_error(ErrorCode::kDisconnected, "libcamera: camera " + d.info.model + " went away");
    }
    if (!ok) {
      lock.unlock();
      stop();
      return make_error(ErrorCode::kTimeout, "libcamera: no frame within " + std::to_string(d.timeout_s) + " s");
    }
  }
  if (request->status() != lc::Request::RequestComplete ||
      buffer->metadata().status != lc::FrameMetadata::FrameSuccess) {
    stop();
    return make_error(ErrorCode::kDevice, "libcamera: request failed or cancelled");
  }
  // Planes of one buffer share a dmabuf here (what FrameBufferAllocator hands out): map it once.
  const auto& planes = buffer->planes();
  size_t map_len = 0;
  for (const auto& p : planes) {
    if (p.fd.get() != planes[0].fd.get()) {
      stop();
      return make_error(ErrorCode::kUnsupported, "libcamera: planes in separate buffers are not handled");
    }
    map_len = std::max<size_t>(map_len, size_t(p.offset) + p.length);
  }
  void* base = mmap(nullptr, map_len, PROT_READ, MAP_SHARED, planes[0].fd.get(), 0);
  if (base == MAP_FAILED) {
    stop();
    return make_error(ErrorCode::kDevice, "libcamera: cannot map the frame buffer");
  }
  const lc::StreamConfiguration& sc = d.config->at(0);
  const PixelBuffer pb{static_cast<const uint8_t*>(base) + planes[0].offset,
                       map_len - planes[0].offset,
                       static_cast<int>(sc.size.width),
                       static_cast<int>(sc.size.height),
                       sc.stride,
                       d.layout,
                       8};
  auto image = to_bgr(pb);
  munmap(base, map_len);

  Frame f;
  const lc::ControlList& meta = request->metadata();
  f.exposure_s = meta.get(lc::controls::ExposureTime).value_or(us) * 1e-6;
  f.gain = meta.get(lc::controls::AnalogueGain).value_or(static_cast<float>(d.gain));
  // SensorTimestamp is the start of exposure of the first line, on CLOCK_MONOTONIC (from the V4L2 buffer).
  timespec mono, real;
  clock_gettime(CLOCK_MONOTONIC, &mono);
  clock_gettime(CLOCK_REALTIME, &real);
  const int64_t mono_ns = mono.tv_sec * 1000000000LL + mono.tv_nsec;
  const int64_t real_ns = real.tv_sec * 1000000000LL + real.tv_nsec;
  f.timestamp_ns = real_ns - (mono_ns - meta.get(lc::controls::SensorTimestamp).value_or(mono_ns));
  f.sequence = d.captures++;
  f.bits = 8;
  stop();
  if (!image) return image.error();
  f.image = std::move(image.value());
  return f;
}

void register_libcamera_backend(BackendRegistry& registry) {
  registry.add_camera("libcamera",
                      [](const nlohmann::json& settings, RigContext&) -> Result<std::unique_ptr<Camera>> {
                        auto config = LibcameraConfig::parse(settings);
                        if (!config) return config.error();
                        return LibcameraCamera::create(config.value());
                      },
                      {.check = settings_check(LibcameraConfig::parse)});
}

DeviceKind list_libcamera_devices() {
  DeviceKind k{"libcamera cameras", {}, ""};
  auto cameras = list_libcamera_cameras();
  if (!cameras)
    k.note = cameras.error().message;
  else
    for (const auto& c : cameras.value()) k.devices.push_back({c, ""});
  return k;
}

}  // namespace vdrig::rig

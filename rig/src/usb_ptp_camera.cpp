#include "usb_ptp_camera.hpp"

#include <libusb.h>
#include <cmath>
#include <cstdio>
#include <thread>

#include "backends.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"

namespace vdrig::rig {
namespace {

std::string descriptor_string(libusb_device_handle* h, uint8_t index) {
  if (!h || index == 0) return {};
  unsigned char buf[256];
  const int n = libusb_get_string_descriptor_ascii(h, index, buf, sizeof buf);
  return n > 0 ? std::string(reinterpret_cast<char*>(buf), static_cast<size_t>(n)) : std::string();
}

bool has_still_image_interface(libusb_device* dev, const libusb_device_descriptor& d) {
  if (d.bDeviceClass == LIBUSB_CLASS_IMAGE) return true;
  libusb_config_descriptor* cfg = nullptr;
  if (libusb_get_active_config_descriptor(dev, &cfg) != 0 && libusb_get_config_descriptor(dev, 0, &cfg) != 0)
    return false;
  bool found = false;
  for (int i = 0; i < cfg->bNumInterfaces && !found; ++i)
    for (int a = 0; a < cfg->interface[i].num_altsetting && !found; ++a)
      found = cfg->interface[i].altsetting[a].bInterfaceClass == LIBUSB_CLASS_IMAGE;
  libusb_free_config_descriptor(cfg);
  return found;
}

std::optional<uint16_t> parse_hex16(const std::string& s) {
  unsigned v = 0;
  char tail = 0;
  if (s.empty() || s.size() > 6 || std::sscanf(s.c_str(), "%x%c", &v, &tail) != 1 || v > 0xffff) return std::nullopt;
  return static_cast<uint16_t>(v);
}

std::string hex4(uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04x", v);
  return buf;
}

// ---- libusb transport ----

class LibusbTransport final : public ptp::PtpTransport {
 public:
  static Result<std::unique_ptr<ptp::PtpTransport>> open(const UsbPtpConfig& c);
  ~LibusbTransport() override;

  Status send(const uint8_t* data, size_t n, int timeout_ms) override {
    int done = 0;
    // libusb takes a non-const buffer for both directions; it does not write to an OUT buffer.
    int r = libusb_bulk_transfer(h_, ep_out_, const_cast<uint8_t*>(data), static_cast<int>(n), &done, timeout_ms);
    if (r != 0) return usb_error("bulk write", r, ep_out_);
    if (static_cast<size_t>(done) != n)
      return make_error(ErrorCode::kIo,
                        "usb-ptp: bulk write sent " + std::to_string(done) + " of " + std::to_string(n) + " bytes");
    // A transfer ends with a short packet: one that fills whole packets needs a zero-length packet after it, or
    // the camera keeps waiting for the rest of the container.
    if (n > 0 && n % out_packet_bytes_ == 0) {
      r = libusb_bulk_transfer(h_, ep_out_, const_cast<uint8_t*>(data), 0, &done, timeout_ms);
      if (r != 0) return usb_error("zero-length packet", r, ep_out_);
    }
    return Status::ok();
  }

  Result<size_t> receive(uint8_t* data, size_t max, int timeout_ms) override {
    int done = 0;
    const int r = libusb_bulk_transfer(h_, ep_in_, data, static_cast<int>(max), &done, timeout_ms);
    if (r != 0) return usb_error("bulk read", r, ep_in_);
    return static_cast<size_t>(done);
  }

  Result<std::vector<uint8_t>> receive_event(int timeout_ms) override {
    if (ep_int_ == 0) {  // a camera without an interrupt pipe: no events ever (capture then times out)
      std::this_thread::sleep_for(std::chrono::milliseconds(timeout_ms));
      return make_error(ErrorCode::kTimeout, "usb-ptp: the camera has no interrupt (event) endpoint");
    }
    std::vector<uint8_t> buf(64);  // an event container is 12..24 bytes
    int done = 0;
    // libusb treats a timeout of 0 as "wait for ever": a poll is 1 ms.
    const int r = libusb_interrupt_transfer(h_, ep_int_, buf.data(), static_cast<int>(buf.size()), &done,
                                            timeout_ms <= 0 ? 1 : timeout_ms);
    if (r != 0) return usb_error("interrupt read", r, ep_int_);
    buf.resize(static_cast<size_t>(done));
    return buf;
  }

 private:
  LibusbTransport() = default;

  Error usb_error(const char* what, int r, uint8_t ep) {
    const std::string msg = std::string("usb-ptp: ") + what + ": " + libusb_strerror(r);
    switch (r) {
      case LIBUSB_ERROR_NO_DEVICE:
        return make_error(ErrorCode::kDisconnected, msg + " (unplugged or switched off?)");
      case LIBUSB_ERROR_TIMEOUT:
        return make_error(ErrorCode::kTimeout, msg);
      case LIBUSB_ERROR_PIPE:
        // The camera stalled the endpoint (it rejected the transfer). The halt must be cleared on our side too, or
        // every later transfer on that endpoint fails.
        libusb_clear_halt(h_, ep);
        return make_error(ErrorCode::kDevice, msg + " (endpoint stalled; halt cleared)");
      case LIBUSB_ERROR_OVERFLOW:
        return make_error(ErrorCode::kCorrupt, msg + " (the camera sent more than a container holds)");
      default:
        return make_error(ErrorCode::kIo, msg);
    }
  }

  libusb_context* ctx_ = nullptr;
  libusb_device_handle* h_ = nullptr;
  int interface_ = -1;
  bool claimed_ = false, detached_ = false;
  uint8_t ep_in_ = 0, ep_out_ = 0, ep_int_ = 0;
  size_t out_packet_bytes_ = 512;
};

Result<std::unique_ptr<ptp::PtpTransport>> LibusbTransport::open(const UsbPtpConfig& c) {
  std::unique_ptr<LibusbTransport> t(new LibusbTransport());
  if (const int r = libusb_init(&t->ctx_); r != 0)
    return make_error(ErrorCode::kUnsupported, std::string("libusb: ") + libusb_strerror(r));
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(t->ctx_, &list);
  if (n < 0)
    return make_error(ErrorCode::kIo,
                      std::string("libusb: cannot list devices: ") + libusb_strerror(static_cast<int>(n)));
  libusb_device* dev = nullptr;
  int seen = 0;
  for (ssize_t i = 0; i < n && !dev; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0 || !has_still_image_interface(list[i], d)) continue;
    if ((c.vendor_id && d.idVendor != *c.vendor_id) || (c.product_id && d.idProduct != *c.product_id)) continue;
    if (seen++ != c.index) continue;
    dev = libusb_ref_device(list[i]);
    log::get("rig")->info("usb-ptp: opening {}:{} on bus {} address {}", hex4(d.idVendor), hex4(d.idProduct),
                          libusb_get_bus_number(dev), libusb_get_device_address(dev));
  }
  libusb_free_device_list(list, 1);
  if (!dev)
    return make_error(ErrorCode::kNotFound, "usb-ptp: " + std::to_string(seen) +
                                                " matching still-image camera(s) on USB, index " +
                                                std::to_string(c.index) + " asked");
  const int r = libusb_open(dev, &t->h_);
  if (r != 0) {
    libusb_unref_device(dev);
    return make_error(r == LIBUSB_ERROR_NO_DEVICE ? ErrorCode::kDisconnected : ErrorCode::kDevice,
                      std::string("usb-ptp: cannot open the camera: ") + libusb_strerror(r) +
                          (r == LIBUSB_ERROR_ACCESS ? " (no permission: add a udev rule for its vendor id)" : ""));
  }
  // The still-image interface and its three endpoints: bulk in, bulk out, interrupt in (events).
  libusb_config_descriptor* cfg = nullptr;
  if (libusb_get_active_config_descriptor(dev, &cfg) != 0 || !cfg) {
    libusb_unref_device(dev);
    return make_error(ErrorCode::kDevice, "usb-ptp: cannot read the camera's configuration descriptor");
  }
  int alt = 0;
  for (int i = 0; i < cfg->bNumInterfaces && t->interface_ < 0; ++i)
    for (int a = 0; a < cfg->interface[i].num_altsetting && t->interface_ < 0; ++a) {
      const libusb_interface_descriptor& id = cfg->interface[i].altsetting[a];
      if (id.bInterfaceClass != LIBUSB_CLASS_IMAGE) continue;
      t->interface_ = id.bInterfaceNumber;
      alt = id.bAlternateSetting;
      for (int e = 0; e < id.bNumEndpoints; ++e) {
        const libusb_endpoint_descriptor& ep = id.endpoint[e];
        const int type = ep.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK;
        const bool in = (ep.bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN;
        if (type == LIBUSB_TRANSFER_TYPE_BULK && in) t->ep_in_ = ep.bEndpointAddress;
        if (type == LIBUSB_TRANSFER_TYPE_BULK && !in) {
          t->ep_out_ = ep.bEndpointAddress;
          t->out_packet_bytes_ = std::max<size_t>(8, ep.wMaxPacketSize & 0x7FF);
        }
        if (type == LIBUSB_TRANSFER_TYPE_INTERRUPT && in) t->ep_int_ = ep.bEndpointAddress;
      }
    }
  libusb_free_config_descriptor(cfg);
  libusb_unref_device(dev);
  if (t->interface_ < 0 || t->ep_in_ == 0 || t->ep_out_ == 0)
    return make_error(ErrorCode::kUnsupported, "usb-ptp: no still-image interface with bulk in/out endpoints");
  // On Linux no kernel driver normally binds PTP, but some cameras also offer mass storage on the same interface.
  if (libusb_kernel_driver_active(t->h_, t->interface_) == 1) {
    if (const int d = libusb_detach_kernel_driver(t->h_, t->interface_); d != 0)
      return make_error(ErrorCode::kDevice,
                        std::string("usb-ptp: cannot detach the kernel driver: ") + libusb_strerror(d));
    t->detached_ = true;
  }
  if (const int cr = libusb_claim_interface(t->h_, t->interface_); cr != 0)
    return make_error(cr == LIBUSB_ERROR_NO_DEVICE ? ErrorCode::kDisconnected : ErrorCode::kDevice,
                      std::string("usb-ptp: cannot claim the camera's interface: ") + libusb_strerror(cr) +
                          (cr == LIBUSB_ERROR_BUSY ? " (another program holds it: a desktop's gvfs-gphoto2-volume-"
                                                     "monitor, gphoto2, shotwell; stop it or unmount the camera)"
                                                   : ""));
  t->claimed_ = true;
  if (alt != 0) libusb_set_interface_alt_setting(t->h_, t->interface_, alt);
  // A run that died mid-transfer can leave endpoints halted; clearing them costs nothing when they are not.
  for (uint8_t ep : {t->ep_in_, t->ep_out_, t->ep_int_})
    if (ep != 0) libusb_clear_halt(t->h_, ep);
  return std::unique_ptr<ptp::PtpTransport>(std::move(t));
}

LibusbTransport::~LibusbTransport() {
  if (h_) {
    if (claimed_) libusb_release_interface(h_, interface_);
    if (detached_) libusb_attach_kernel_driver(h_, interface_);
    libusb_close(h_);
  }
  if (ctx_) libusb_exit(ctx_);
}

bool is_image_format(uint16_t f) {
  return f == ptp::kFormatExifJpeg || f == ptp::kFormatJfif || f == ptp::kFormatTiff || f == ptp::kFormatPng;
}

}  // namespace

Result<std::unique_ptr<ptp::PtpTransport>> open_usb_ptp_transport(const UsbPtpConfig& config) {
  return LibusbTransport::open(config);
}

Result<std::vector<UsbStillCamera>> list_usb_still_cameras() {
  libusb_context* ctx = nullptr;
  if (const int r = libusb_init(&ctx); r != 0)
    return make_error(ErrorCode::kUnsupported, std::string("libusb: ") + libusb_strerror(r));
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  if (n < 0) {
    libusb_exit(ctx);
    return make_error(ErrorCode::kIo,
                      std::string("libusb: cannot list devices: ") + libusb_strerror(static_cast<int>(n)));
  }
  std::vector<UsbStillCamera> out;
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0 || !has_still_image_interface(list[i], d)) continue;
    UsbStillCamera c;
    c.vendor_id = d.idVendor;
    c.product_id = d.idProduct;
    c.bus = libusb_get_bus_number(list[i]);
    c.address = libusb_get_device_address(list[i]);
    libusb_device_handle* h = nullptr;
    if (libusb_open(list[i], &h) == 0) {  // fails without udev permissions; the ids are still useful
      c.manufacturer = descriptor_string(h, d.iManufacturer);
      c.product = descriptor_string(h, d.iProduct);
      c.serial = descriptor_string(h, d.iSerialNumber);
      libusb_close(h);
    }
    out.push_back(std::move(c));
  }
  libusb_free_device_list(list, 1);
  libusb_exit(ctx);
  return out;
}

// ---- settings ----

Result<UsbPtpConfig> UsbPtpConfig::parse(const nlohmann::json& settings) {
  Settings s(settings, "camera usb-ptp", {"backend"});
  UsbPtpConfig c;
  for (const auto& [key, dest] : {std::pair{"vendor_id", &c.vendor_id}, std::pair{"product_id", &c.product_id}}) {
    if (!s.has(key)) continue;
    const std::string v = s.string(key, "");
    *dest = parse_hex16(v);
    if (!*dest) s.fail(std::string("\"") + key + "\" must be a hex id such as \"04a9\", got \"" + v + "\"");
  }
  c.index = static_cast<int>(s.integer("index", 0, 0, 127));
  c.timeout_s = s.number("timeout_s", c.timeout_s, 0.1, 120.0);
  c.capture_timeout_s = s.number("capture_timeout_s", c.capture_timeout_s, 0.1, 600.0);
  c.complete_grace_s = s.number("complete_grace_s", c.complete_grace_s, 0.0, 60.0);
  c.keep_on_card = s.boolean("keep_on_card", c.keep_on_card);
  c.base_iso = s.number("base_iso", c.base_iso, 1.0, 1e6);
  c.busy_retries = static_cast<int>(s.integer("busy_retries", c.busy_retries, 0, 1000));
  s.reject_unknown({"vendor_id", "product_id", "index", "timeout_s", "capture_timeout_s", "complete_grace_s",
                    "keep_on_card", "base_iso", "busy_retries"});
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

ptp::SessionOptions UsbPtpConfig::session_options() const {
  ptp::SessionOptions o;
  o.timeout_ms = static_cast<int>(std::lround(timeout_s * 1000.0));
  o.busy_retries = busy_retries;
  return o;
}

// ---- the camera ----

nlohmann::json UsbPtpConfig::effective() const {
  const auto hex = [](const std::optional<uint16_t>& v) -> nlohmann::json {
    if (!v) return "any";
    char buf[8];
    std::snprintf(buf, sizeof buf, "%04x", *v);
    return buf;
  };
  return {{"backend", "usb-ptp"},
          {"vendor_id", hex(vendor_id)},
          {"product_id", hex(product_id)},
          {"index", index},
          {"timeout_s", timeout_s},
          {"capture_timeout_s", capture_timeout_s},
          {"complete_grace_s", complete_grace_s},
          {"keep_on_card", keep_on_card},
          {"base_iso", base_iso},
          {"busy_retries", busy_retries}};
}

Result<std::unique_ptr<Camera>> UsbPtpCamera::create(const nlohmann::json& settings) {
  auto config = UsbPtpConfig::parse(settings);
  if (!config) return config.error();
  const UsbPtpConfig c = config.value();
  auto cam = create_with(
      c, [c] { return open_usb_ptp_transport(c); }, c.session_options());
  if (!cam) return cam.error();
  return std::unique_ptr<Camera>(std::move(cam.value()));
}

Result<std::unique_ptr<UsbPtpCamera>> UsbPtpCamera::create_with(UsbPtpConfig config, PtpTransportFactory open_transport,
                                                                ptp::SessionOptions options) {
  std::unique_ptr<UsbPtpCamera> cam(new UsbPtpCamera(std::move(config), std::move(open_transport), options));
  VDRIG_TRY(cam->connect());
  return cam;
}

UsbPtpCamera::UsbPtpCamera(UsbPtpConfig config, PtpTransportFactory open_transport, ptp::SessionOptions options)
    : StillCamera("usb-ptp", config.keep_on_card),
      config_(std::move(config)),
      open_transport_(std::move(open_transport)),
      options_(options) {}

UsbPtpCamera::~UsbPtpCamera() { drop(); }

void UsbPtpCamera::drop() {
  if (session_ && session_->is_open()) (void)session_->close();  // best effort: the camera may be gone
  session_.reset();
  transport_.reset();
}

Error UsbPtpCamera::failed(Error e) {
  if (e.code == ErrorCode::kDisconnected || e.code == ErrorCode::kTimeout || e.code == ErrorCode::kCorrupt ||
      e.code == ErrorCode::kIo) {
    // The stream may hold half a container: start over with a new session on the next call.
    session_.reset();
    transport_.reset();
  }
  return e;
}

std::string UsbPtpCamera::name() const {
  std::string n = device_info_.manufacturer;
  if (!device_info_.model.empty()) n += (n.empty() ? "" : " ") + device_info_.model;
  return n.empty() ? "PTP camera" : n;
}

Status UsbPtpCamera::connect() {
  auto t = open_transport_();
  if (!t) return t.error();
  transport_ = std::move(t.value());
  session_ = std::make_unique<ptp::PtpSession>(*transport_, options_);
  auto di = session_->get_device_info();
  if (!di) return failed(di.error());
  device_info_ = std::move(di.value());
  if (Status s = session_->open(); !s) return failed(s.error());

  exposure_desc_.reset();
  iso_desc_.reset();
  const auto describe = [&](uint16_t prop, std::optional<ptp::PropDesc>& out) -> Status {
    if (!device_info_.supports_property(prop) || !device_info_.supports_operation(ptp::kGetDevicePropDesc))
      return Status::ok();
    auto d = session_->get_prop_desc(prop);
    if (d) {
      out = std::move(d.value());
      return Status::ok();
    }
    if (d.error().code == ErrorCode::kDevice || d.error().code == ErrorCode::kUnsupported) {
      log::get("rig")->warn("usb-ptp: {}", d.error().message);  // advertised but not described: treat as absent
      return Status::ok();
    }
    return failed(d.error());
  };
  VDRIG_TRY(describe(ptp::kExposureTime, exposure_desc_));
  VDRIG_TRY(describe(ptp::kExposureIndex, iso_desc_));

  info_.model = name();
  info_.bits = 8;
  info_.auto_exposure_on = !exposure_desc_ || !exposure_desc_->writable;
  if (exposure_desc_) {
    const auto lo = exposure_desc_->nearest(1e-9), hi = exposure_desc_->nearest(1e12);
    if (lo && hi) {
      info_.min_exposure_s = *lo * 1e-4;
      info_.max_exposure_s = *hi * 1e-4;
    }
    if (exposure_desc_->current > 0 && exposure_desc_->current != 0xFFFFFFFF)
      used_.exposure_s = exposure_desc_->current * 1e-4;
  }
  if (iso_desc_ && iso_desc_->current > 0) used_.gain = iso_desc_->current / config_.base_iso;
  log::get("rig")->info("usb-ptp: {} (serial {}), {} operations; exposure {}, ISO {}, capture {}", info_.model,
                        device_info_.serial_number, device_info_.operations.size(),
                        exposure_desc_ ? (exposure_desc_->writable ? "settable" : "read-only") : "absent",
                        iso_desc_ ? (iso_desc_->writable ? "settable" : "read-only") : "absent",
                        device_info_.supports_operation(ptp::kInitiateCapture) ? "yes" : "NO");
  return Status::ok();
}

Status UsbPtpCamera::apply_exposure() {
  if (!exposure_desc_)
    return make_error(ErrorCode::kUnsupported,
                      "usb-ptp: " + name() + " does not offer ExposureTime (0x500D) over PTP; a bracket needs it");
  if (!exposure_desc_->writable)
    return make_error(ErrorCode::kUnsupported, "usb-ptp: " + name() +
                                                   " reports ExposureTime as read-only (is the mode dial on manual "
                                                   "\"M\"?)");
  const auto units = exposure_desc_->nearest(asked_.exposure_s * 1e4);  // ExposureTime counts 0.1 ms
  if (!units) return make_error(ErrorCode::kUnsupported, "usb-ptp: the camera lists no usable exposure time");
  if (*units != exposure_desc_->current) {
    if (Status s = session_->set_prop_value(ptp::kExposureTime, exposure_desc_->data_type, *units); !s)
      return failed(s.error());
    exposure_desc_->current = *units;
  }
  used_.exposure_s = *units * 1e-4;

  if (iso_desc_ && iso_desc_->writable) {
    const auto iso = iso_desc_->nearest(asked_.gain * config_.base_iso);
    if (iso && *iso != iso_desc_->current) {
      if (Status s = session_->set_prop_value(ptp::kExposureIndex, iso_desc_->data_type, *iso); !s)
        return failed(s.error());
      iso_desc_->current = *iso;
    }
    if (iso) used_.gain = *iso / config_.base_iso;
  } else {
    used_.gain = iso_desc_ && iso_desc_->current > 0 ? iso_desc_->current / config_.base_iso : 1.0;
    if (std::abs(used_.gain - asked_.gain) > 0.01 * asked_.gain)
      log::get("rig")->warn("usb-ptp: ISO cannot be set on {}; gain {} asked, {} used", name(), asked_.gain,
                            used_.gain);
  }
  return Status::ok();
}

Result<std::vector<StillFile>> UsbPtpCamera::trigger() {
  if (!device_info_.supports_operation(ptp::kInitiateCapture))
    return make_error(ErrorCode::kUnsupported,
                      "usb-ptp: " + name() +
                          " does not offer InitiateCapture (0x100E): it cannot be triggered over standard PTP (many "
                          "cameras need a vendor extension for that; try the gphoto2 backend)");
  const int timeout_ms = static_cast<int>(std::lround((config_.capture_timeout_s + used_.exposure_s) * 1000.0));
  auto handles = session_->capture(timeout_ms, static_cast<int>(std::lround(config_.complete_grace_s * 1000.0)));
  if (!handles) return failed(handles.error());
  // RAW+JPEG gives two objects: StillCamera takes the first one OpenCV can decode.
  std::vector<StillFile> files;
  for (uint32_t h : *handles) {
    auto oi = session_->get_object_info(h);
    if (!oi) return failed(oi.error());
    StillFile f;
    f.name = oi->filename.empty() ? "object " + std::to_string(h) : oi->filename;
    f.handle = h;
    f.decodable = is_image_format(oi->format);
    f.size_bytes = oi->compressed_size == 0xFFFFFFFF ? 0 : oi->compressed_size;
    files.push_back(std::move(f));
  }
  return files;
}

Result<std::vector<uint8_t>> UsbPtpCamera::download(const StillFile& file) {
  auto bytes = session_->get_object(file.handle);
  if (!bytes) return failed(bytes.error());
  return bytes;
}

Status UsbPtpCamera::remove(const StillFile& file) { return session_->delete_object(file.handle); }

void register_usb_ptp_backend(BackendRegistry& registry) {
  registry.add_camera("usb-ptp",
                      [](const nlohmann::json& settings, RigContext&) { return UsbPtpCamera::create(settings); },
                      {.check = settings_check(UsbPtpConfig::parse)});
}

DeviceKind list_usb_ptp_devices() {
  DeviceKind k{"USB PTP still cameras", {}, ""};
  auto cameras = list_usb_still_cameras();
  if (!cameras) {
    k.note = cameras.error().message;
    return k;
  }
  for (const auto& c : cameras.value()) {
    char ids[32];
    std::snprintf(ids, sizeof ids, "%04x:%04x", c.vendor_id, c.product_id);
    std::string summary = std::string("vendor_id ") + std::string(ids, 4) + ", product_id " + std::string(ids + 5);
    if (c.product.empty())
      summary += "; cannot open it for its names (permissions? see docs/hardware.md)";
    else
      summary += "; " + c.manufacturer + " " + c.product + (c.serial.empty() ? "" : ", serial " + c.serial);
    k.devices.push_back({"usb:" + std::to_string(c.bus) + ":" + std::to_string(c.address), summary});
  }
  return k;
}

}  // namespace vdrig::rig

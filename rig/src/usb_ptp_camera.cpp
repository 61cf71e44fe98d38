#include "usb_ptp_camera.hpp"

#include <libusb.h>

#include <cstdio>

#include "backends.hpp"
#include "settings.hpp"
#include "vdrig/core/log.hpp"

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

}  // namespace

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
      libusb_close(h);
    }
    out.push_back(std::move(c));
  }
  libusb_free_device_list(list, 1);
  libusb_exit(ctx);
  return out;
}

Result<std::unique_ptr<Camera>> UsbPtpCamera::create(const nlohmann::json& settings) {
  Settings s(settings, "camera usb-ptp");
  std::optional<uint16_t> vendor, product;
  for (const auto& [key, dest] : {std::pair{"vendor_id", &vendor}, std::pair{"product_id", &product}}) {
    if (!s.has(key)) continue;
    const std::string v = s.string(key, "");
    *dest = parse_hex16(v);
    if (!*dest) s.fail(std::string("\"") + key + "\" must be a hex id such as \"04a9\", got \"" + v + "\"");
  }
  const int index = static_cast<int>(s.integer("index", 0, 0, 127));
  s.reject_unknown({"vendor_id", "product_id", "index"});
  if (!s.is_valid(nullptr)) return s.error();
  auto all = list_usb_still_cameras();
  if (!all) return all.error();
  std::vector<UsbStillCamera> match;
  for (const auto& c : *all)
    if ((!vendor || c.vendor_id == *vendor) && (!product || c.product_id == *product)) match.push_back(c);
  if (index >= static_cast<int>(match.size()))
    return make_error(ErrorCode::kNotFound, "usb-ptp: " + std::to_string(match.size()) +
                                                " matching still-image camera(s) on USB, index " +
                                                std::to_string(index) + " asked");
  const UsbStillCamera& c = match[static_cast<size_t>(index)];
  log::get("rig")->info("usb-ptp: found {}:{} {} {} on bus {} address {}", hex4(c.vendor_id), hex4(c.product_id),
                        c.manufacturer, c.product, c.bus, c.address);
  return std::unique_ptr<Camera>(new UsbPtpCamera(c));
}

Result<CameraInfo> UsbPtpCamera::info() {
  CameraInfo i;
  i.model = dev_.manufacturer.empty() && dev_.product.empty()
                ? "USB " + hex4(dev_.vendor_id) + ":" + hex4(dev_.product_id)
                : dev_.manufacturer + " " + dev_.product;
  return i;  // size and exposure range are unknown without a PTP session
}

Status UsbPtpCamera::set_exposure(double, double) {
  return make_error(ErrorCode::kUnsupported,
                    "usb-ptp: exposure control over PTP is not implemented (discovery only); use a v4l2 or libcamera "
                    "camera, or drive this one with gphoto2");
}

Result<Frame> UsbPtpCamera::capture() {
  return make_error(ErrorCode::kUnsupported,
                    "usb-ptp: PTP capture is not implemented (discovery only); use a v4l2 or libcamera camera, or "
                    "drive this one with gphoto2");
}

void register_usb_ptp_backend(BackendRegistry& registry) {
  registry.add_camera("usb-ptp",
                      [](const nlohmann::json& settings, RigContext&) { return UsbPtpCamera::create(settings); });
}

}  // namespace vdrig::rig

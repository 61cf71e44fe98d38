#include "gphoto2_camera.hpp"

#include <gphoto2/gphoto2.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>

#if defined(__SANITIZE_ADDRESS__)
#define VDRIG_GPHOTO2_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define VDRIG_GPHOTO2_ASAN 1
#endif
#endif
#ifdef VDRIG_GPHOTO2_ASAN
#include <sanitizer/lsan_interface.h>
#endif

#include "backends.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"

namespace vdrig::rig {

// ---- settings ----

Result<Gphoto2Config> Gphoto2Config::parse(const nlohmann::json& settings) {
  Settings s(settings, "camera gphoto2", {"backend"});
  Gphoto2Config c;
  c.model = s.string("model", "");
  c.port = s.string("port", "");
  if (c.model.empty() != c.port.empty())
    s.fail("\"model\" and \"port\" go together (as `vdrig rig devices` lists them), or neither for autodetect");
  c.index = static_cast<int>(s.integer("index", 0, 0, 127));
  const std::string target = s.string("capture_target", "ram", {"ram", "card", "camera"});
  c.capture_target = target == "card" ? Target::kCard : target == "camera" ? Target::kCamera : Target::kRam;
  c.keep_on_card = s.boolean("keep_on_card", c.keep_on_card);
  c.base_iso = s.number("base_iso", c.base_iso, 1.0, 1e6);
  if (s.has("aperture")) c.aperture = s.number("aperture", 8.0, 0.5, 128.0);
  c.event_grace_s = s.number("event_grace_s", c.event_grace_s, 0.0, 30.0);
  s.reject_unknown(
      {"model", "port", "index", "capture_target", "keep_on_card", "base_iso", "aperture", "event_grace_s"});
  if (!s.is_valid(nullptr)) return s.error();
  return c;
}

// ---- libgphoto2 ----

namespace {

/// What another program holding the camera usually is; named in the busy error.
constexpr const char* kLikelyHolders =
    "another program holds the camera: a desktop's gvfs-gphoto2-volume-monitor (or gvfsd-gphoto2), KDE's "
    "kiod/solid, gphoto2, Shotwell, darktable, digiKam, Entangle, or another vdrig; stop it or unmount the "
    "camera (docs/hardware.md)";

ErrorCode code_of(int r, bool open) {
  switch (r) {
    case GP_ERROR_TIMEOUT:
      return ErrorCode::kTimeout;
    case GP_ERROR_IO_USB_CLAIM:
    case GP_ERROR_IO_LOCK:
    case GP_ERROR_CAMERA_BUSY:
    case GP_ERROR_CAMERA_ERROR:
      return ErrorCode::kDevice;
    case GP_ERROR_MODEL_NOT_FOUND:
    case GP_ERROR_UNKNOWN_PORT:
    case GP_ERROR_FILE_NOT_FOUND:
    case GP_ERROR_DIRECTORY_NOT_FOUND:
      return ErrorCode::kNotFound;
    case GP_ERROR_IO_USB_FIND:  // the device is gone from the bus
      return open ? ErrorCode::kDisconnected : ErrorCode::kNotFound;
    case GP_ERROR_IO:
    case GP_ERROR_IO_READ:
    case GP_ERROR_IO_WRITE:
    case GP_ERROR_IO_INIT:
    case GP_ERROR_IO_UPDATE:
    case GP_ERROR_IO_USB_CLEAR_HALT:
      return open ? ErrorCode::kDisconnected : ErrorCode::kIo;
    case GP_ERROR_NOT_SUPPORTED:
    case GP_ERROR_LIBRARY:
      return ErrorCode::kUnsupported;
    case GP_ERROR_CORRUPTED_DATA:
      return ErrorCode::kCorrupt;
    case GP_ERROR_NO_SPACE:
      return ErrorCode::kNoSpace;
    case GP_ERROR_CANCEL:
      return ErrorCode::kCancelled;
    case GP_ERROR_BAD_PARAMETERS:
      return ErrorCode::kInvalidArgument;
    default:
      return ErrorCode::kDevice;  // GP_ERROR and the camlibs' own: the driver reported a failure
  }
}

void collect_entries(CameraWidget* w, std::vector<ConfigEntry>& out) {
  CameraWidgetType type;
  if (gp_widget_get_type(w, &type) != GP_OK) return;
  if (type == GP_WIDGET_WINDOW || type == GP_WIDGET_SECTION) {
    for (int i = 0, n = gp_widget_count_children(w); i < n; ++i) {
      CameraWidget* child = nullptr;
      if (gp_widget_get_child(w, i, &child) == GP_OK) collect_entries(child, out);
    }
    return;
  }
  ConfigEntry e;
  const char* text = nullptr;
  if (gp_widget_get_name(w, &text) == GP_OK && text) e.name = text;
  if (gp_widget_get_label(w, &text) == GP_OK && text) e.label = text;
  int ro = 0;
  if (gp_widget_get_readonly(w, &ro) == GP_OK) e.readonly = ro != 0;
  if (type == GP_WIDGET_TEXT || type == GP_WIDGET_RADIO || type == GP_WIDGET_MENU) {
    const char* v = nullptr;
    if (gp_widget_get_value(w, &v) == GP_OK && v) e.value = v;
  } else if (type == GP_WIDGET_RANGE) {
    float v = 0;
    if (gp_widget_get_value(w, &v) == GP_OK) e.value = std::to_string(v);
  } else if (type == GP_WIDGET_TOGGLE || type == GP_WIDGET_DATE) {
    int v = 0;
    if (gp_widget_get_value(w, &v) == GP_OK) e.value = std::to_string(v);
  }
  if (type == GP_WIDGET_RADIO || type == GP_WIDGET_MENU)
    for (int i = 0, n = gp_widget_count_choices(w); i < n; ++i) {
      const char* c = nullptr;
      if (gp_widget_get_choice(w, i, &c) == GP_OK && c) e.choices.emplace_back(c);
    }
  out.push_back(std::move(e));
}

/// libgphoto2 2.5.30's USB port plugin (libgphoto2_port/.../usb1.so) leaks libusb's device list on every bus scan:
/// autodetect scans once per known camera model, about 22 KB on a machine without cameras, more with devices on the
/// bus; listing the ports leaks one list too. The plugin is dlclose'd before LeakSanitizer runs and has no frame
/// pointers, so its frames are unnamed and the default (fast) unwinder stops there: suppressions in
/// scripts/lsan.supp naming libgphoto2_port, libusb, usb1.so or gp_camera_autodetect were tried and match nothing
/// (they do only with fast_unwind_on_malloc=0, far too slow for the whole suite). Under ASan, leak checking is
/// therefore paused around exactly those libgphoto2 calls; elsewhere this is nothing.
class LibraryLeaksIgnored {
 public:
#ifdef VDRIG_GPHOTO2_ASAN
  LibraryLeaksIgnored() { __lsan_disable(); }
  ~LibraryLeaksIgnored() { __lsan_enable(); }
#else
  LibraryLeaksIgnored() {}  // user-provided: a guard object, not an unused variable
  ~LibraryLeaksIgnored() {}
#endif
  LibraryLeaksIgnored(const LibraryLeaksIgnored&) = delete;
  LibraryLeaksIgnored& operator=(const LibraryLeaksIgnored&) = delete;
};

void remember_error(GPContext*, const char* text, void* data) {
  if (text) *static_cast<std::string*>(data) = text;
}

}  // namespace

Error gphoto2_error(int r, const std::string& what, bool open, const std::string& context_text) {
  const ErrorCode code = code_of(r, open);
  std::string m = "gphoto2: " + what + ": " + gp_result_as_string(r) + " (" + std::to_string(r) + ")";
  if (!context_text.empty()) m += ": " + trim_whitespace(context_text);
  if (r == GP_ERROR_IO_USB_CLAIM || r == GP_ERROR_IO_LOCK) m += std::string("; ") + kLikelyHolders;
  if (code == ErrorCode::kDisconnected) m += " (unplugged or switched off? the next call reopens it)";
  return make_error(code, m);
}

struct Gphoto2Camera::Impl {
  GPContext* context = nullptr;
  ::Camera* camera = nullptr;  // libgphoto2's Camera, not vdrig's
  std::string model, port;
  std::string last_error;  // the context's last error text (the camlib's own words)

  Impl() {
    context = gp_context_new();
    gp_context_set_error_func(context, remember_error, &last_error);
  }
  ~Impl() {
    close();
    gp_context_unref(context);
  }
  void close() {
    if (!camera) return;
    gp_camera_exit(camera, context);  // best effort: the camera may be gone
    gp_camera_unref(camera);
    camera = nullptr;
  }
};

namespace {

/// Autodetect with a context of its own. libgphoto2 loads every port driver for it.
Result<std::vector<Gphoto2Detected>> autodetect(GPContext* context) {
  CameraList* list = nullptr;
  if (const int r = gp_list_new(&list); r < GP_OK) return gphoto2_error(r, "gp_list_new", false);
  const int n = [&] {
    LibraryLeaksIgnored scan;
    return gp_camera_autodetect(list, context);
  }();
  std::vector<Gphoto2Detected> out;
  for (int i = 0; i < n; ++i) {
    const char *name = nullptr, *value = nullptr;
    gp_list_get_name(list, i, &name);
    gp_list_get_value(list, i, &value);
    out.push_back({name ? name : "", value ? value : ""});
  }
  gp_list_free(list);
  if (n < GP_OK) return gphoto2_error(n, "autodetect", false);
  return out;
}

}  // namespace

Result<std::vector<Gphoto2Detected>> list_gphoto2_cameras() {
  GPContext* context = gp_context_new();
  auto r = autodetect(context);
  gp_context_unref(context);
  return r;
}

nlohmann::json Gphoto2Config::effective() const {
  using T = Gphoto2Config::Target;
  return {{"backend", "gphoto2"},
          {"model", model.empty() ? "autodetect" : model},
          {"port", port.empty() ? "autodetect" : port},
          {"index", index},
          {"capture_target", capture_target == T::kRam    ? "ram"
                             : capture_target == T::kCard ? "card"
                                                          : "camera"},
          {"keep_on_card", keep_on_card},
          {"base_iso", base_iso},
          {"aperture", aperture ? nlohmann::json(*aperture) : nlohmann::json("as set on the camera")},
          {"event_grace_s", event_grace_s}};
}

Result<std::unique_ptr<Camera>> Gphoto2Camera::create(const nlohmann::json& settings) {
  auto config = Gphoto2Config::parse(settings);
  if (!config) return config.error();
  auto cam = open(std::move(config.value()));
  if (!cam) return cam.error();
  return std::unique_ptr<Camera>(std::move(cam.value()));
}

Result<std::unique_ptr<Gphoto2Camera>> Gphoto2Camera::open(Gphoto2Config config) {
  std::unique_ptr<Gphoto2Camera> cam(new Gphoto2Camera(std::move(config)));
  VDRIG_TRY(cam->connect());
  return cam;
}

Gphoto2Camera::Gphoto2Camera(Gphoto2Config config)
    : StillCamera("gphoto2", config.keep_on_card), config_(std::move(config)), impl_(std::make_unique<Impl>()) {}

Gphoto2Camera::~Gphoto2Camera() = default;

bool Gphoto2Camera::connected() const { return impl_->camera != nullptr; }

void Gphoto2Camera::drop() { impl_->close(); }

Error Gphoto2Camera::fail(int r, const std::string& what) {
  Error e = gphoto2_error(r, what, connected(), impl_->last_error);
  impl_->last_error.clear();
  if (e.code == ErrorCode::kDisconnected || e.code == ErrorCode::kTimeout) drop();
  return e;
}

Status Gphoto2Camera::connect() {
  std::string model = config_.model, port = config_.port;
  if (model.empty()) {
    auto found = autodetect(impl_->context);
    if (!found) return found.error();
    if (static_cast<int>(found->size()) <= config_.index)
      return make_error(ErrorCode::kNotFound,
                        "gphoto2: libgphoto2 found " + std::to_string(found->size()) + " camera(s), index " +
                            std::to_string(config_.index) +
                            " asked (is it plugged in, switched on and in PTP/PC mode? `vdrig rig devices` lists "
                            "what libgphoto2 sees)");
    model = (*found)[static_cast<size_t>(config_.index)].model;
    port = (*found)[static_cast<size_t>(config_.index)].port;
  }

  // The driver for the model and the port it is on, as gphoto2 --camera/--port chooses them.
  CameraAbilitiesList* abilities_list = nullptr;
  GPPortInfoList* ports = nullptr;
  const auto cleanup = [&] {
    if (abilities_list) gp_abilities_list_free(abilities_list);
    if (ports) gp_port_info_list_free(ports);
  };
  int r = gp_abilities_list_new(&abilities_list);
  if (r >= GP_OK) r = gp_abilities_list_load(abilities_list, impl_->context);
  if (r < GP_OK) {
    cleanup();
    return fail(r, "cannot load libgphoto2's camera drivers");
  }
  const int model_index = gp_abilities_list_lookup_model(abilities_list, model.c_str());
  if (model_index < GP_OK) {
    cleanup();
    return make_error(ErrorCode::kNotFound, "gphoto2: libgphoto2 has no driver for a camera model named \"" + model +
                                                "\" (`gphoto2 --list-cameras` lists the names)");
  }
  CameraAbilities abilities;
  gp_abilities_list_get_abilities(abilities_list, model_index, &abilities);
  r = gp_port_info_list_new(&ports);
  if (r >= GP_OK) {
    LibraryLeaksIgnored scan;
    r = gp_port_info_list_load(ports);
  }
  const int port_index = r >= GP_OK ? gp_port_info_list_lookup_path(ports, port.c_str()) : r;
  if (port_index < GP_OK) {
    cleanup();
    return make_error(ErrorCode::kNotFound, "gphoto2: no port \"" + port + "\" (" + gp_result_as_string(port_index) +
                                                "); ports look like \"usb:001,007\" or \"disk:/media/card\"");
  }
  GPPortInfo port_info;
  gp_port_info_list_get_info(ports, port_index, &port_info);

  ::Camera* camera = nullptr;
  r = gp_camera_new(&camera);
  if (r >= GP_OK) r = gp_camera_set_abilities(camera, abilities);
  if (r >= GP_OK) r = gp_camera_set_port_info(camera, port_info);
  cleanup();
  if (r >= GP_OK) {
    LibraryLeaksIgnored scan;  // opening a USB port scans the bus as well
    r = gp_camera_init(camera, impl_->context);
  }
  if (r < GP_OK) {
    // Not gp_camera_unref: after a failed init libgphoto2 still counts the camera as in use and unref keeps it (a
    // leak LeakSanitizer found); nothing else holds it, so it is freed outright.
    if (camera) gp_camera_free(camera);
    // libgphoto2's USB port answers a bus/address where no device is with "Bad parameters" (or USB_FIND).
    if (port.rfind("usb:", 0) == 0 && (r == GP_ERROR_BAD_PARAMETERS || r == GP_ERROR_IO_USB_FIND))
      return make_error(ErrorCode::kNotFound,
                        "gphoto2: no camera at " + port + " (" + gp_result_as_string(r) +
                            "); the address changes at every plug-in: leave \"model\"/\"port\" out to autodetect, "
                            "or see `vdrig rig devices`");
    return fail(r, "cannot open " + model + " on " + port);
  }
  impl_->camera = camera;
  impl_->model = model;
  impl_->port = port;

  // The configuration: which settings there are, under which names, with which choices.
  config_entries_.clear();
  CameraWidget* window = nullptr;
  r = gp_camera_get_config(camera, &window, impl_->context);
  if (r >= GP_OK) {
    collect_entries(window, config_entries_);
    gp_widget_free(window);
  } else if (r != GP_ERROR_NOT_SUPPORTED) {
    return fail(r, "cannot read the configuration of " + model);
  }
  impl_->last_error.clear();

  // Photos to the camera's RAM where it can: nothing accumulates on the card, and no card is needed.
  if (config_.capture_target != Gphoto2Config::Target::kCamera)
    if (const ConfigEntry* t = find_setting(config_entries_, StillSetting::kCaptureTarget)) {
      const bool ram = config_.capture_target == Gphoto2Config::Target::kRam;
      if (const auto choice = choose_capture_target(t->choices, ram)) {
        if (*choice != t->value) VDRIG_TRY(set_choice(*t, *choice));
      } else {
        log::get("rig")->warn("gphoto2: {} offers no {} capture target (choices: {})", model, ram ? "RAM" : "card",
                              t->choices.size());
      }
    }
  if (config_.aperture) {
    const ConfigEntry* a = find_setting(config_entries_, StillSetting::kAperture, parse_aperture_label);
    const auto choice = a ? choose_stop(a->choices, *config_.aperture, parse_aperture_label) : std::nullopt;
    if (!choice)
      return make_error(ErrorCode::kUnsupported, "gphoto2: " + model +
                                                     " has no settable aperture (tried \"aperture\", \"f-number\"; "
                                                     "a manual lens, or the mode dial not on M?)");
    if (choice->label != a->value) VDRIG_TRY(set_choice(*a, choice->label));
    log::get("rig")->info("gphoto2: aperture f/{} set (f/{} asked)", choice->value, *config_.aperture);
  }

  const ConfigEntry* shutter = find_setting(config_entries_, StillSetting::kShutter, parse_shutter_label);
  const ConfigEntry* iso = find_setting(config_entries_, StillSetting::kIso, parse_iso_label);
  info_.model = model;
  info_.bits = 8;
  info_.auto_exposure_on = shutter == nullptr;
  if (shutter)
    if (const auto range = stop_range(shutter->choices, parse_shutter_label)) {
      info_.min_exposure_s = range->first;
      info_.max_exposure_s = range->second;
    }
  if (shutter)
    if (const auto v = parse_shutter_label(shutter->value)) used_.exposure_s = *v;
  const auto& iso_names = config_names(StillSetting::kIso);
  for (const ConfigEntry& e : config_entries_)  // a read-only ISO still tells the gain used
    if (std::find(iso_names.begin(), iso_names.end(), e.name) != iso_names.end())
      if (const auto v = parse_iso_label(e.value)) used_.gain = *v / config_.base_iso;
  CameraAbilities a;
  const bool can_capture =
      gp_camera_get_abilities(camera, &a) >= GP_OK && (a.operations & GP_OPERATION_CAPTURE_IMAGE) != 0;
  log::get("rig")->info("gphoto2: {} on {}: {} settings; shutter {}, ISO {}, remote capture {}", model, port,
                        config_entries_.size(), shutter ? shutter->name : "not settable",
                        iso ? iso->name : "not settable", can_capture ? "yes" : "NO");
  return Status::ok();
}

Status Gphoto2Camera::set_choice(const ConfigEntry& entry, const std::string& choice) {
  CameraWidget* w = nullptr;
  int r = gp_camera_get_single_config(impl_->camera, entry.name.c_str(), &w, impl_->context);
  if (r >= GP_OK) r = gp_widget_set_value(w, choice.c_str());
  if (r >= GP_OK) r = gp_camera_set_single_config(impl_->camera, entry.name.c_str(), w, impl_->context);
  if (w) gp_widget_free(w);
  if (r < GP_OK) return fail(r, "cannot set " + entry.name + " to \"" + choice + "\"");
  for (ConfigEntry& e : config_entries_)
    if (e.name == entry.name) e.value = choice;
  return Status::ok();
}

Status Gphoto2Camera::apply_exposure() {
  const ConfigEntry* shutter = find_setting(config_entries_, StillSetting::kShutter, parse_shutter_label);
  if (!shutter)
    return make_error(ErrorCode::kUnsupported,
                      "gphoto2: " + impl_->model +
                          " has no settable shutter speed (tried \"shutterspeed\", \"shutterspeed2\"; is the mode "
                          "dial on manual \"M\"?); a bracket needs it");
  // find_setting returned an entry with a choice that parses, so there is a nearest one.
  const auto s = choose_stop(shutter->choices, asked_.exposure_s, parse_shutter_label);
  if (s->label != shutter->value) VDRIG_TRY(set_choice(*shutter, s->label));
  used_.exposure_s = s->value;

  if (const ConfigEntry* iso = find_setting(config_entries_, StillSetting::kIso, parse_iso_label)) {
    const auto i = choose_stop(iso->choices, asked_.gain * config_.base_iso, parse_iso_label);
    if (i->label != iso->value) VDRIG_TRY(set_choice(*iso, i->label));
    used_.gain = i->value / config_.base_iso;
  } else if (std::abs(used_.gain - asked_.gain) > 0.01 * asked_.gain) {
    log::get("rig")->warn("gphoto2: ISO cannot be set on {} (Auto, or no \"iso\" setting); gain {} asked, {} used",
                          impl_->model, asked_.gain, used_.gain);
  }
  return Status::ok();
}

Result<std::vector<StillFile>> Gphoto2Camera::list_files(const std::string& folder) {
  VDRIG_TRY(ensure_connected());
  CameraList* list = nullptr;
  gp_list_new(&list);
  const int r = gp_camera_folder_list_files(impl_->camera, folder.c_str(), list, impl_->context);
  std::vector<StillFile> out;
  for (int i = 0; r >= GP_OK && i < gp_list_count(list); ++i) {
    const char* name = nullptr;
    gp_list_get_name(list, i, &name);
    out.push_back(StillFile{name ? name : "", folder, 0, name && is_decodable_image_name(name), 0});
  }
  gp_list_free(list);
  if (r < GP_OK) return fail(r, "cannot list " + folder);
  for (StillFile& f : out) {
    CameraFileInfo fi;
    std::memset(&fi, 0, sizeof fi);
    if (gp_camera_file_get_info(impl_->camera, f.folder.c_str(), f.name.c_str(), &fi, impl_->context) >= GP_OK &&
        (fi.file.fields & GP_FILE_INFO_SIZE))
      f.size_bytes = fi.file.size;
  }
  impl_->last_error.clear();
  return out;
}

Result<std::vector<StillFile>> Gphoto2Camera::trigger() {
  CameraFilePath path;
  std::memset(&path, 0, sizeof path);
  const int r = gp_camera_capture(impl_->camera, GP_CAPTURE_IMAGE, &path, impl_->context);
  if (r == GP_ERROR_NOT_SUPPORTED)
    return make_error(ErrorCode::kUnsupported, "gphoto2: " + impl_->model +
                                                   " cannot be triggered remotely through libgphoto2 (its driver has "
                                                   "no image capture)");
  if (r < GP_OK) return fail(r, "capture on " + impl_->model);
  std::vector<CameraFilePath> paths{path};
  // RAW+JPEG: the second file comes as an event. Wait a little for it (or for CAPTURE_COMPLETE).
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(config_.event_grace_s);
  while (std::chrono::steady_clock::now() < until) {
    const int left_ms = static_cast<int>(
        std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now()).count());
    CameraEventType type;
    void* data = nullptr;
    const int e = gp_camera_wait_for_event(impl_->camera, std::max(1, left_ms), &type, &data, impl_->context);
    if (e == GP_ERROR_NOT_SUPPORTED) break;  // a driver without events: the capture's own file is all there is
    if (e < GP_OK) {
      free(data);
      return fail(e, "waiting for the capture's files");
    }
    if (type == GP_EVENT_FILE_ADDED && data) {
      const auto* added = static_cast<const CameraFilePath*>(data);
      const bool known = std::any_of(paths.begin(), paths.end(), [&](const CameraFilePath& p) {
        return std::strcmp(p.name, added->name) == 0 && std::strcmp(p.folder, added->folder) == 0;
      });
      if (!known) paths.push_back(*added);  // some drivers announce the captured file again
    }
    free(data);  // libgphoto2 hands the event's data over (malloc'd)
    if (type == GP_EVENT_CAPTURE_COMPLETE || type == GP_EVENT_TIMEOUT) break;
  }
  std::vector<StillFile> files;
  for (const CameraFilePath& p : paths) {
    StillFile f{p.name, p.folder, 0, is_decodable_image_name(p.name), 0};
    CameraFileInfo fi;
    std::memset(&fi, 0, sizeof fi);
    if (gp_camera_file_get_info(impl_->camera, p.folder, p.name, &fi, impl_->context) >= GP_OK &&
        (fi.file.fields & GP_FILE_INFO_SIZE))
      f.size_bytes = fi.file.size;
    files.push_back(std::move(f));
  }
  impl_->last_error.clear();
  return files;
}

Result<std::vector<uint8_t>> Gphoto2Camera::download(const StillFile& file) {
  CameraFile* cf = nullptr;
  int r = gp_file_new(&cf);
  if (r >= GP_OK)
    r = gp_camera_file_get(impl_->camera, file.folder.c_str(), file.name.c_str(), GP_FILE_TYPE_NORMAL, cf,
                           impl_->context);
  const char* data = nullptr;
  unsigned long size = 0;
  if (r >= GP_OK) r = gp_file_get_data_and_size(cf, &data, &size);
  std::vector<uint8_t> bytes;
  if (r >= GP_OK && data)
    bytes.assign(reinterpret_cast<const uint8_t*>(data), reinterpret_cast<const uint8_t*>(data) + size);
  if (cf) gp_file_unref(cf);
  if (r < GP_OK) return fail(r, "cannot download " + file.folder + "/" + file.name);
  return bytes;
}

Status Gphoto2Camera::remove(const StillFile& file) {
  const int r = gp_camera_file_delete(impl_->camera, file.folder.c_str(), file.name.c_str(), impl_->context);
  if (r < GP_OK) return fail(r, "cannot delete " + file.folder + "/" + file.name);
  return Status::ok();
}

void register_gphoto2_backend(BackendRegistry& registry) {
  registry.add_camera("gphoto2",
                      [](const nlohmann::json& settings, RigContext&) { return Gphoto2Camera::create(settings); },
                      {.check = settings_check(Gphoto2Config::parse)});
}

DeviceKind list_gphoto2_devices() {
  DeviceKind k{"gphoto2 cameras (libgphoto2)", {}, ""};
  auto cameras = list_gphoto2_cameras();
  if (!cameras)
    k.note = cameras.error().message;
  else
    for (const auto& c : cameras.value())  // the model and port a "gphoto2" camera section takes
      k.devices.push_back({c.port, "model \"" + c.model + "\""});
  return k;
}

}  // namespace vdrig::rig

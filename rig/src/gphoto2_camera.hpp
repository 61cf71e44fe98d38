// "gphoto2" camera: a still camera through libgphoto2 (Debian's libgphoto2-dev), beside usb-ptp's own PTP stack.
// libgphoto2 brings the vendor extensions (Canon EOS and Nikon remote capture, their shutter/ISO settings) and the
// camera list gphoto2 users know; the capture flow, exposure rounding and shared errors are StillCamera's.
//
// Settings (JSON "camera" section):
//   "model" / "port" (optional, together: libgphoto2's model name and port, e.g. "Canon EOS 600D" and
//   "usb:001,007", as `vdrig rig devices` or `gphoto2 --auto-detect` print them; without them the `index`-th camera
//   autodetect finds is used), "index" (0), "capture_target" ("ram": photos go to the camera's RAM where it has a
//   capturetarget setting, so the card is untouched; "card": to the memory card; "camera": left as set),
//   "keep_on_card" (false: each photo is deleted from the camera once downloaded), "base_iso" (100: gain 1 is this
//   ISO; gain g asks for ISO g * base_iso), "aperture" (optional f-number set once at open, nearest the lens
//   offers), "event_grace_s" (0.5: after the capture returned, how long to wait for more files such as the JPEG of
//   RAW+JPEG).
// Errors: kNotFound (no camera, or the configured model/port does not exist); kDevice naming the likely holders
// when another program has claimed the camera (GP_ERROR_IO_USB_CLAIM: gvfs-gphoto2-volume-monitor, ...);
// kDisconnected for an I/O failure once open (unplugged, switched off; the next call reopens); kTimeout;
// kUnsupported for a camera without settable shutter speed or remote capture; kCorrupt for a photo that does not
// decode.
//
// The label parsing and choice functions below are pure (no camera needed) and tested on their own.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "still_camera.hpp"

namespace vdrig::rig {

// ---- pure: gphoto2's setting labels ----

/// A shutter-speed label in seconds: "1/250", "1/3", "2", "0.5", "0.0080s" (generic PTP), "1\"3" (1.3 s, Sony),
/// "30\"". nullopt for bulb/time modes and anything else ("bulb", "Bulb", "Time", "x 200").
std::optional<double> parse_shutter_label(const std::string& label);
/// An ISO label: "100", "ISO 200", "6400". nullopt for "Auto", "Auto ISO" and the like.
std::optional<double> parse_iso_label(const std::string& label);
/// An aperture label as f-number: "f/5.6", "5.6", "F8". nullopt for "implicit auto" and the like.
std::optional<double> parse_aperture_label(const std::string& label);

/// One choice of a radio/menu setting, with its parsed value.
struct StopChoice {
  size_t index = 0;
  std::string label;
  double value = 0.0;
};
using LabelParser = std::optional<double> (*)(const std::string&);
/// The choice whose parsed value is nearest `want` in stops; labels that do not parse are never chosen.
std::optional<StopChoice> choose_stop(const std::vector<std::string>& labels, double want, LabelParser parse);
/// Smallest and largest parsed value among `labels` (nullopt when none parses).
std::optional<std::pair<double, double>> stop_range(const std::vector<std::string>& labels, LabelParser parse);

/// One setting of a camera's configuration tree (a leaf widget), as gp_camera_get_config lists it.
struct ConfigEntry {
  std::string name;   // "shutterspeed"
  std::string label;  // "Shutter Speed"
  bool readonly = false;
  std::string value;                 // current value as text
  std::vector<std::string> choices;  // radio and menu widgets
};

enum class StillSetting { kShutter, kIso, kAperture, kCaptureTarget };
/// The config names one setting has across libgphoto2's drivers (camlibs/ptp2/config.c), in the order tried:
/// shutter "shutterspeed" (generic PTP, Canon, Sony, Fuji, Olympus), "shutterspeed2" (Nikon); ISO "iso"; aperture
/// "aperture" (Canon, Fuji, Olympus), "f-number" (generic PTP, Nikon, Sony); "capturetarget".
const std::vector<std::string>& config_names(StillSetting setting);
/// The first entry named as `setting` that is writable and offers at least one choice `parse` reads (for
/// kCaptureTarget: any writable one with choices); nullptr when the camera has none.
const ConfigEntry* find_setting(const std::vector<ConfigEntry>& config, StillSetting setting,
                                LabelParser parse = nullptr);
/// The capturetarget choice for RAM ("Internal RAM", "SDRAM") or card ("Memory card", "Card"); nullopt if none.
std::optional<std::string> choose_capture_target(const std::vector<std::string>& choices, bool ram);

// ---- the camera ----

/// A libgphoto2 result (GP_ERROR_*) as an Error naming `what` failed: kTimeout, kDevice for a claimed camera
/// (GP_ERROR_IO_USB_CLAIM; the message names the likely holders), kNotFound for a missing model/port/file (and a
/// device gone from the bus before open), kDisconnected for I/O failures once `open`, kUnsupported, kCorrupt, ...
/// `context_text` is the camlib's own message, appended.
Error gphoto2_error(int gp_result, const std::string& what, bool open, const std::string& context_text = "");

struct Gphoto2Config {
  std::string model, port;  // both or neither
  int index = 0;
  enum class Target { kRam, kCard, kCamera } capture_target = Target::kRam;
  bool keep_on_card = false;
  double base_iso = 100.0;
  std::optional<double> aperture;
  double event_grace_s = 0.5;
  /// Validates every key up front (kInvalidArgument listing each problem).
  static Result<Gphoto2Config> parse(const nlohmann::json& settings);
};

/// A camera libgphoto2 found.
struct Gphoto2Detected {
  std::string model, port;
};
/// gp_camera_autodetect: every camera libgphoto2 sees (USB, mounted mass storage).
Result<std::vector<Gphoto2Detected>> list_gphoto2_cameras();

class Gphoto2Camera final : public StillCamera {
 public:
  static Result<std::unique_ptr<Camera>> create(const nlohmann::json& settings);
  /// Opens the camera at once (the tests' entry point: model "Directory Browse", port "disk:/folder").
  static Result<std::unique_ptr<Gphoto2Camera>> open(Gphoto2Config config);
  ~Gphoto2Camera() override;

  std::string backend() const override { return "gphoto2"; }
  // info(): model from libgphoto2's abilities; exposure range from the shutter-speed choices; auto_exposure_on
  // when the camera has no writable shutter speed (mode dial not on M, or no such setting).

  /// The camera's configuration, as read at the last connect (empty for a camera without one).
  const std::vector<ConfigEntry>& config() const { return config_entries_; }
  /// Files in `folder` on the camera (gp_camera_folder_list_files), for collect() and the tests.
  Result<std::vector<StillFile>> list_files(const std::string& folder);

 private:
  struct Impl;  // libgphoto2's handles, in the .cpp (its headers stay private to it)
  explicit Gphoto2Camera(Gphoto2Config config);
  bool connected() const override;
  Status connect() override;
  Status apply_exposure() override;
  Result<std::vector<StillFile>> trigger() override;
  Result<std::vector<uint8_t>> download(const StillFile& file) override;
  Status remove(const StillFile& file) override;
  Status set_choice(const ConfigEntry& entry, const std::string& choice);
  /// A libgphoto2 result as an Error; I/O failures and timeouts once open drop the camera (the next call reopens).
  Error fail(int gp_result, const std::string& what);
  void drop();

  Gphoto2Config config_;
  std::unique_ptr<Impl> impl_;
  std::vector<ConfigEntry> config_entries_;
};

}  // namespace vdrig::rig

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
// Reading the camera's setting labels and choosing among them is gphoto2_labels.hpp (pure, tested on its own).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "gphoto2_labels.hpp"
#include "still_camera.hpp"

namespace vdrig::rig {

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
  /// The settings as the backend uses them, defaults filled in, in the section's JSON keys (`vdrig rig check`).
  nlohmann::json effective() const;
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

// What the still-camera backends (usb-ptp, gphoto2) share behind the Camera interface. A still camera stores each
// photograph as a file on itself (card or RAM): a capture triggers the shutter, lists the files the shot stored,
// downloads the first one vdrig decodes (JPEG, TIFF, PNG; RAW is refused with the reason), decodes it and then
// deletes them all from the camera (unless kept on the card). A shot that fails any of this leaves its files there.
// Exposure time and ISO are discrete stops on such cameras: the backend sets the one nearest in stops (nearest_stop)
// and every frame reports the exposure really used.
//
// A backend implements the hooks (connect, apply_exposure, trigger, download, remove); this class orders them,
// re-applies the asked exposure after a reconnect, and produces the shared errors:
//   kInvalidArgument  set_exposure with a non-positive exposure or gain;
//   kUnsupported      a shot that stored no decodable file (RAW only);
//   kCorrupt          a download shorter or longer than the camera announced, or one that does not decode.
// Every other error is the backend's (kNotFound, kDisconnected, kTimeout, kDevice, ...).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

/// One file a shot left on the camera.
struct StillFile {
  std::string name;         // the camera's file name (messages, gphoto2's file argument)
  std::string folder;       // gphoto2: the folder on the camera; empty for PTP
  uint32_t handle = 0;      // PTP: the object handle
  bool decodable = false;   // JPEG, TIFF or PNG: what decode_image reads
  uint64_t size_bytes = 0;  // what the camera says the file holds; 0 when it does not say
};

/// Exposure time and gain (ISO / base ISO) as set on the camera; exposure 0 when not known.
struct StillExposure {
  double exposure_s = 0.0;
  double gain = 1.0;
};

/// Index of the value nearest `want` in photographic stops (|log2(value / want)|, ties to the first listed);
/// values that are not finite and positive are never chosen. nullopt when `want` is not positive or nothing is.
std::optional<size_t> nearest_stop(const std::vector<double>& values, double want);

/// JPEG, TIFF or PNG by the file name's extension (case-insensitive), for cameras that give no format code.
bool is_decodable_image_name(const std::string& name);

class StillCamera : public Camera {
 public:
  /// Connects when needed; info_ as the backend filled it (width/height of the last photograph, 0 before).
  Result<CameraInfo> info() override;
  /// Remembers the request, connects when needed and lets the backend set the nearest stops.
  Status set_exposure(double exposure_s, double gain) final;
  /// trigger() then collect(); the timestamp is taken just before the trigger (the shutter opens a little later).
  Result<Frame> capture() final;
  /// The second half of a capture: downloads the first decodable of `files` and decodes it, ignoring the EXIF
  /// orientation (a tilted rig must not rotate the picture); once decoded, deletes all of them from the camera
  /// (unless keep_on_card; a failed delete is only logged). On any error they stay on the camera. Public so that
  /// files already on the camera can be fetched the same way.
  Result<Frame> collect(const std::vector<StillFile>& files);

 protected:
  /// `tag` prefixes every message ("usb-ptp", "gphoto2").
  StillCamera(std::string tag, bool keep_on_card) : tag_(std::move(tag)), keep_on_card_(keep_on_card) {}

  virtual bool connected() const = 0;
  /// Opens the camera (only called when !connected()); fills info_ and, where the camera tells, used_.
  virtual Status connect() = 0;
  /// Sets the stops nearest `asked_` and records what was set in used_.
  virtual Status apply_exposure() = 0;
  /// Releases the shutter and returns the files the shot stored.
  virtual Result<std::vector<StillFile>> trigger() = 0;
  virtual Result<std::vector<uint8_t>> download(const StillFile& file) = 0;
  virtual Status remove(const StillFile& file) = 0;
  virtual bool can_remove() const { return true; }
  /// Called with the errors this class makes about a download (wrong size): a backend whose link may now be out of
  /// step drops it here. Returns the error.
  virtual Error link_error(Error e) { return e; }

  /// Connects when not connected; after a (re)connect the exposure asked before is applied again (a camera that
  /// was switched off forgets it).
  Status ensure_connected();

  const std::string tag_;
  CameraInfo info_;
  StillExposure asked_{0.01, 1.0};  // what set_exposure asked
  StillExposure used_;              // what the camera was set to
  bool exposure_asked_ = false;

 private:
  bool keep_on_card_;
  uint64_t captures_ = 0;
};

}  // namespace vdrig::rig

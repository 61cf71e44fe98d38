// gphoto2's setting labels, read and chosen among without a camera (no libgphoto2 call): the shutter, ISO and
// aperture labels of every vendor's driver, the nearest stop, and which config names each driver uses
// (camlibs/ptp2/config.c of libgphoto2). The gphoto2 camera backend (gphoto2_camera.hpp) drives the camera with
// them; they are built whether or not libgphoto2 is, and tested on their own (tests/rig/test_gphoto2_labels.cpp).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vdrig::rig {

/// `s` without the white space around it (labels and libgphoto2's messages come padded).
std::string trim_whitespace(const std::string& s);

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

}  // namespace vdrig::rig

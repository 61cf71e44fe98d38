#include "gphoto2_labels.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "still_camera.hpp"

namespace vdrig::rig {

std::string trim_whitespace(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

/// A plain decimal ("30", "0.5", ".3") at `pos`: no sign, no exponent, so that labels like "x 200" or "-1" never
/// read as numbers. Advances `pos` past it.
std::optional<double> decimal(const std::string& s, size_t& pos) {
  const size_t start = pos;
  while (pos < s.size() && std::isdigit(static_cast<unsigned char>(s[pos]))) ++pos;
  if (pos < s.size() && s[pos] == '.') {
    ++pos;
    while (pos < s.size() && std::isdigit(static_cast<unsigned char>(s[pos]))) ++pos;
  }
  const std::string text = s.substr(start, pos - start);
  if (text.empty() || text == ".") {
    pos = start;
    return std::nullopt;
  }
  return std::strtod(text.c_str(), nullptr);
}

/// The whole of `s` is one positive decimal.
std::optional<double> whole_positive(const std::string& s) {
  size_t pos = 0;
  const auto v = decimal(s, pos);
  if (!v || pos != s.size() || !(*v > 0.0)) return std::nullopt;
  return v;
}

}  // namespace

std::optional<double> parse_shutter_label(const std::string& label) {
  std::string s = trim_whitespace(label);
  // A trailing unit: "0.0080s" (libgphoto2's generic ExposureTime), "1/250 s", "2 sec".
  for (const char* unit : {"sec", "s"}) {
    const size_t n = std::strlen(unit);
    if (s.size() > n && lower(s.substr(s.size() - n)) == unit) {
      s = trim_whitespace(s.substr(0, s.size() - n));
      break;
    }
  }
  size_t pos = 0;
  const auto a = decimal(s, pos);
  if (!a) return std::nullopt;  // "bulb", "Bulb", "Time", "x 200", "Auto"
  double v = *a;
  if (pos < s.size() && s[pos] == '/') {  // "1/250", "10/1250"
    ++pos;
    const auto b = decimal(s, pos);
    if (!b || !(*b > 0.0)) return std::nullopt;
    v = *a / *b;
  } else if (pos < s.size() && s[pos] == '"') {  // seconds mark: "30\"", or Sony's "1\"3" for 1.3 s
    ++pos;
    const size_t digits = pos;
    while (pos < s.size() && std::isdigit(static_cast<unsigned char>(s[pos]))) ++pos;
    if (pos > digits) {
      if (std::floor(*a) != *a) return std::nullopt;  // "1.5\"3" is no label
      v = *a + std::strtod(s.substr(digits, pos - digits).c_str(), nullptr) / std::pow(10.0, double(pos - digits));
    }
  }
  if (pos != s.size() || !(v > 0.0) || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<double> parse_iso_label(const std::string& label) {
  std::string s = trim_whitespace(label);
  if (lower(s.substr(0, 3)) == "iso") s = trim_whitespace(s.substr(3));
  return whole_positive(s);  // "Auto", "Auto ISO", "Hi 1", "Lo 1" do not read
}

std::optional<double> parse_aperture_label(const std::string& label) {
  std::string s = trim_whitespace(label);
  if (s.size() > 2 && lower(s.substr(0, 2)) == "f/")
    s = s.substr(2);
  else if (s.size() > 1 && lower(s.substr(0, 1)) == "f")
    s = s.substr(1);
  return whole_positive(trim_whitespace(s));
}

std::optional<StopChoice> choose_stop(const std::vector<std::string>& labels, double want, LabelParser parse) {
  std::vector<double> values;
  values.reserve(labels.size());
  for (const std::string& l : labels) values.push_back(parse(l).value_or(NAN));  // NAN: never chosen
  const auto i = nearest_stop(values, want);
  if (!i) return std::nullopt;
  return StopChoice{*i, labels[*i], values[*i]};
}

std::optional<std::pair<double, double>> stop_range(const std::vector<std::string>& labels, LabelParser parse) {
  std::optional<std::pair<double, double>> r;
  for (const std::string& l : labels)
    if (const auto v = parse(l)) r = r ? std::pair{std::min(r->first, *v), std::max(r->second, *v)} : std::pair{*v, *v};
  return r;
}

const std::vector<std::string>& config_names(StillSetting setting) {
  static const std::vector<std::string> shutter{"shutterspeed", "shutterspeed2"};
  static const std::vector<std::string> iso{"iso"};
  static const std::vector<std::string> aperture{"aperture", "f-number"};
  static const std::vector<std::string> target{"capturetarget"};
  switch (setting) {
    case StillSetting::kShutter:
      return shutter;
    case StillSetting::kIso:
      return iso;
    case StillSetting::kAperture:
      return aperture;
    case StillSetting::kCaptureTarget:
      break;
  }
  return target;
}

const ConfigEntry* find_setting(const std::vector<ConfigEntry>& config, StillSetting setting, LabelParser parse) {
  for (const std::string& name : config_names(setting))
    for (const ConfigEntry& e : config) {
      if (e.name != name || e.readonly || e.choices.empty()) continue;
      if (!parse || std::any_of(e.choices.begin(), e.choices.end(), [&](const std::string& c) { return parse(c); }))
        return &e;
    }
  return nullptr;
}

std::optional<std::string> choose_capture_target(const std::vector<std::string>& choices, bool ram) {
  for (const std::string& c : choices)
    if (lower(c).find(ram ? "ram" : "card") != std::string::npos) return c;
  return std::nullopt;
}

}  // namespace vdrig::rig

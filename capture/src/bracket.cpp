#include "vdrig/capture/bracket.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <set>
#include <sstream>

namespace vdrig::capture {
namespace {

std::vector<std::string> split(std::string_view s, char sep) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t p = s.find(sep, start);
    out.emplace_back(s.substr(start, p == std::string_view::npos ? std::string_view::npos : p - start));
    if (p == std::string_view::npos) break;
    start = p + 1;
  }
  return out;
}

bool parse_number(const std::string& text, double* value) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (errno != 0 || end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

bool parse_int(const std::string& text, int* value) {
  if (text.empty() || text.size() > 9) return false;
  for (char c : text)
    if (c < '0' || c > '9') return false;
  *value = std::atoi(text.c_str());
  return true;
}

Error invalid(std::string_view spec, const std::string& why) {
  return make_error(ErrorCode::kInvalidArgument, "bracket '" + std::string(spec) + "': " + why);
}

}  // namespace

bool BracketSpec::is_valid(std::string* why) const {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (kind == Kind::kFixed) {
    if (exposures_s.empty()) return fail("a fixed bracket needs at least one exposure");
    std::set<double> seen;
    for (double e : exposures_s) {
      if (!std::isfinite(e) || !(e > 0)) return fail("exposures must be positive (got " + std::to_string(e) + ")");
      if (!seen.insert(e).second) return fail("duplicate exposure " + std::to_string(e) + " s");
    }
    return true;
  }
  if (!std::isfinite(ceiling_s) || !std::isfinite(floor_s) || !(floor_s > 0))
    return fail("auto floor and ceiling must be positive");
  if (floor_s > ceiling_s) return fail("auto floor exceeds the ceiling");
  if (max_frames() > 64) return fail("auto ceiling/floor span more than 64 halvings");
  if (roi && (roi->x < 0 || roi->y < 0 || roi->width <= 0 || roi->height <= 0))
    return fail("region of interest needs x, y >= 0 and a positive size");
  return true;
}

int BracketSpec::max_frames() const {
  if (kind == Kind::kFixed) return static_cast<int>(exposures_s.size());
  if (!(floor_s > 0) || !(ceiling_s >= floor_s)) return 1;
  // Halvings e = ceiling / 2^k that stay >= floor (with a little slack for rounding).
  return 1 + static_cast<int>(std::floor(std::log2(ceiling_s / floor_s) + 1e-9));
}

std::string BracketSpec::to_spec() const {
  std::ostringstream os;
  os.precision(9);
  if (kind == Kind::kFixed) {
    os << "fixed:";
    for (size_t i = 0; i < exposures_s.size(); ++i) os << (i ? "," : "") << exposures_s[i];
  } else {
    os << "auto:" << ceiling_s << ":" << floor_s;
    if (roi) os << "@" << roi->x << "," << roi->y << "," << roi->width << "," << roi->height;
  }
  return os.str();
}

Result<BracketSpec> parse_bracket(std::string_view spec) {
  BracketSpec b;
  if (spec.rfind("fixed:", 0) == 0) {
    b.kind = BracketSpec::Kind::kFixed;
    for (const auto& part : split(spec.substr(6), ',')) {
      double e = 0;
      if (!parse_number(part, &e)) return invalid(spec, "'" + part + "' is not a number of seconds");
      b.exposures_s.push_back(e);
    }
  } else if (spec == "auto" || spec.rfind("auto:", 0) == 0 || spec.rfind("auto@", 0) == 0) {
    b.kind = BracketSpec::Kind::kAuto;
    std::string_view rest = spec.substr(4);
    const size_t at = rest.find('@');
    const std::string_view limits = rest.substr(0, at);
    if (!limits.empty()) {
      const auto parts = split(limits.substr(1), ':');
      if (parts.size() > 2) return invalid(spec, "auto takes at most CEILING_S:FLOOR_S");
      if (!parse_number(parts[0], &b.ceiling_s)) return invalid(spec, "ceiling '" + parts[0] + "' is not a number");
      if (parts.size() == 2 && !parse_number(parts[1], &b.floor_s))
        return invalid(spec, "floor '" + parts[1] + "' is not a number");
    }
    if (at != std::string_view::npos) {
      const auto parts = split(rest.substr(at + 1), ',');
      RegionOfInterest r;
      if (parts.size() != 4 || !parse_int(parts[0], &r.x) || !parse_int(parts[1], &r.y) ||
          !parse_int(parts[2], &r.width) || !parse_int(parts[3], &r.height))
        return invalid(spec, "region of interest must be @X,Y,W,H in whole pixels");
      b.roi = r;
    }
  } else {
    return invalid(spec, "expected 'fixed:E1,E2,...' or 'auto[:CEILING_S[:FLOOR_S]][@X,Y,W,H]'");
  }
  std::string why;
  if (!b.is_valid(&why)) return invalid(spec, why);
  return b;
}

bool frame_saturated(const Frame& frame, const std::optional<RegionOfInterest>& roi) {
  if (frame.image.empty()) return false;
  cv::Mat view = frame.image;
  if (roi) {
    const cv::Rect r = cv::Rect(roi->x, roi->y, roi->width, roi->height) & cv::Rect(0, 0, view.cols, view.rows);
    if (r.empty()) return false;
    view = view(r);
  }
  double max_value = 0;
  cv::minMaxLoc(view.clone().reshape(1), nullptr, &max_value);
  return max_value >= (1 << frame.bits) - 1;
}

}  // namespace vdrig::capture

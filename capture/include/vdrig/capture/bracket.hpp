// Exposure brackets: which exposures to take at each view.
//
// Spec grammar (no spaces):
//   bracket := 'fixed:' E (',' E)*                         the same exposures (seconds) at every view
//            | 'auto' [':' CEILING_S [':' FLOOR_S]] ['@' X ',' Y ',' W ',' H]
// `auto` starts at the ceiling exposure and halves it until no pixel (of the region of interest X,Y,W,H in pixels,
// or of the whole image) is saturated, or the next exposure would fall below the floor. Every frame taken is
// recorded with its exposure, so an auto view has 1..(1 + log2(ceiling / floor)) frames.
// Defaults: ceiling 1 s, floor 1e-4 s. Fixed exposures must be positive and distinct.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vdrig/core/frame.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::capture {

struct RegionOfInterest {
  int x = 0, y = 0, width = 0, height = 0;  // pixels
};

struct BracketSpec {
  enum class Kind { kFixed, kAuto };
  Kind kind = Kind::kFixed;
  std::vector<double> exposures_s;      // kFixed: in capture order
  double ceiling_s = 1.0;               // kAuto: first exposure
  double floor_s = 1e-4;                // kAuto: never below this
  std::optional<RegionOfInterest> roi;  // kAuto: where saturation is looked for (whole image when absent)

  /// Fixed: non-empty, every exposure finite and > 0, no duplicates. Auto: 0 < floor <= ceiling, finite, ROI of
  /// positive size at non-negative offsets. `why` gets the first violation.
  bool is_valid(std::string* why = nullptr) const;
  /// Largest number of frames one view can take (fixed: the count; auto: halvings from ceiling to floor + 1).
  int max_frames() const;
  /// Canonical spec text (parse_bracket(to_spec()) gives back an equal spec up to float printing).
  std::string to_spec() const;
};

/// Parses and validates a spec; kInvalidArgument naming the reason (duplicate, non-positive, bad number, ...).
Result<BracketSpec> parse_bracket(std::string_view spec);

/// True when any pixel (of `roi` clipped to the image, or the whole image) is at the maximum code of the frame's
/// bit depth.
bool frame_saturated(const Frame& frame, const std::optional<RegionOfInterest>& roi);

}  // namespace vdrig::capture

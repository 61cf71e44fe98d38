// RTI light lists (`.lp` files): the light direction of every photograph of a Reflectance Transformation Imaging
// stack (a fixed camera, one light position per image), as RTIBuilder, relight-cli and the light domes write them.
//
// Format: the first non-empty line is the image count N; then N lines `FILENAME X Y Z` (whitespace separated; the
// file name may contain spaces: the last three fields are the direction). X, Y, Z is the direction toward the
// light in the image frame (x right, y up, z toward the camera); it need not be unit and is normalised here. Blank
// lines are skipped. Windows paths (`C:\stack\img_001.jpg`) from domes' software are resolved by their last path
// component beside the .lp when the path itself does not exist.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::rti {

/// One photograph of the stack and the direction of its light.
struct LightPosition {
  std::filesystem::path image;  // as resolved against the .lp file's folder (not checked for existence here)
  Vec3d direction;              // unit, toward the light
};

/// Parses .lp text; `folder` resolves relative image names. kCorrupt naming the line for: a count line that is
/// not a positive integer, a line without a name and three numbers, a zero (or non-finite) direction, and a count
/// that differs from the number of image lines ("count line says 289, the file lists 288 images").
Result<std::vector<LightPosition>> parse_light_positions(const std::string& text, const std::filesystem::path& folder);

/// Reads and parses an .lp file (at most 16 MiB). kNotFound when missing.
Result<std::vector<LightPosition>> read_light_positions(const std::filesystem::path& lp_file);

/// The .lp file of a stack: `path` itself when it is a file, else the single *.lp file in the folder `path`
/// (kNotFound when there is none, kInvalidArgument naming them when there are several).
Result<std::filesystem::path> find_light_positions(const std::filesystem::path& path);

}  // namespace vdrig::rti

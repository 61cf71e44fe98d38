// Reading input files safely: only regular files are opened, so a directory, FIFO or device given where a file is
// expected is a clear error value instead of an abort (a directory) or a hang (a FIFO with no writer).
#pragma once

#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig {

/// Largest file read_regular_file() and read_json_file() accept by default (manifests, rig configs and calibration
/// files are kilobytes; a larger one is not one of them).
inline constexpr std::size_t kMaxJsonFileBytes = 64u << 20;

/// Ok when `path` names an existing regular file (symbolic links followed). Errors: kNotFound when nothing is
/// there; kInvalidArgument naming what it is instead ("is a directory", "is a FIFO"); kIo when stat fails.
Status check_regular_file(const std::filesystem::path& path);

/// The whole content of a regular file. It is opened non-blocking and checked with fstat before reading, so a FIFO
/// never blocks and a file swapped for a directory after check_regular_file() is still refused. Errors as
/// check_regular_file(), kInvalidArgument when the file is larger than `max_bytes`, kIo when reading fails.
Result<std::string> read_regular_file(const std::filesystem::path& path, std::size_t max_bytes);

/// A JSON document whose top level is an object (every JSON file vdrig reads is one), from a regular file of at
/// most kMaxJsonFileBytes. Errors as read_regular_file(); kCorrupt for invalid JSON (the message gives the line
/// and column), for a key repeated within one object (parse_json_strict: every one named with its path) and for a
/// top level that is not an object.
Result<nlohmann::json> read_json_file(const std::filesystem::path& path);

}  // namespace vdrig

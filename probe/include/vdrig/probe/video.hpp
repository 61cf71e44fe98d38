// PNG frames to an MP4 through ffmpeg, when it is installed (`vdrig probe animate`): vdrig does not link a video
// encoder, and the frames are complete without the MP4.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::probe {

/// An executable named `name` in a folder of PATH, or empty.
std::filesystem::path find_on_path(const std::string& name);

/// Runs argv[0] (a path) with `argv` (no shell) and waits: its exit status, or -1 when it could not start or did not
/// exit normally.
int run_program(const std::vector<std::string>& argv);

/// frames_dir/frame_%04d.png encoded by ffmpeg into frames_dir/mp4_name (H.264, yuv420p, sizes rounded down to
/// even) at `fps` frames per second. The MP4's path; kNotFound when ffmpeg is not on PATH; kInvalidArgument for
/// fps <= 0; kIo when ffmpeg fails.
Result<std::filesystem::path> encode_frames_mp4(const std::filesystem::path& frames_dir, double fps,
                                                const std::string& mp4_name = "animation.mp4");

}  // namespace vdrig::probe

// What the fidelity tests that capture a Blender session share (test_blender_session.cpp, test_blender_light.cpp,
// test_blender_roundtrip.cpp): a sample .blend from scripts/blender_scenes.py and the capture request of a short
// session of the "blender" camera on the simulated stage.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::pipeline::test_blender {

inline double since_s(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// Writes scripts/blender_scenes.py's `sample` (a .blend of Principled BSDF) to dir/<sample>.blend with the
/// `blender` executable and returns that path; a failure of the script is a test failure (the caller then finds no
/// file there).
inline std::filesystem::path make_sample_blend(const std::filesystem::path& dir, const std::string& sample,
                                               const std::string& blender = "blender") {
  const std::string make = blender + " --background --factory-startup --python " +
                           (std::filesystem::path(VDRIG_SOURCE_DIR) / "scripts" / "blender_scenes.py").string() +
                           " -- " + dir.string() + " " + sample + " >/dev/null 2>&1";
  EXPECT_EQ(std::system(make.c_str()), 0) << make;
  return dir / (sample + ".blend");
}

/// A session of the "blender" camera rendering `blend` on the simulated stage, written to out_dir: the demo's field of
/// view at 256 x 192, lens distortion on; Cycles at 16 samples a pixel; brackets of 1, 1/4 and 1/16 s. The .blend's
/// surface is 1 m square, vdrig's corner markers added (the built-in scenes' layout, which the "scene" key gives); the
/// light is the simulated one (tests that record a lamp or leave out the markers change rig_config).
inline CaptureRequest blender_capture_request(const std::filesystem::path& out_dir, const std::filesystem::path& blend,
                                              const std::string& scheme) {
  CaptureRequest req;
  req.out_dir = out_dir;
  req.rig_config = {
      {"stage", {{"backend", "sim"}}},
      {"camera", {{"backend", "blender"}, {"samples", 16}, {"blend", blend.string()}}},
      {"light", {{"backend", "sim"}}},
      {"sim", {{"scene", "patchwork"}, {"camera", {{"width", 256}, {"height", 192}, {"fx", 320.0}, {"fy", 320.0}}}}}};
  req.scheme = scheme;
  req.exposures_s = {1.0, 0.25, 0.0625};
  return req;
}

}  // namespace vdrig::pipeline::test_blender

// Helpers shared by the probe tests: synthetic maps and the real probes in tests/data/probes (CC0,
// tests/data/README.md).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "vdrig/probe/irradiance_error.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::probe::testing {

inline const char* const kRealProbes[] = {"courtyard", "interior", "studio"};

inline std::filesystem::path real_probe_path(const std::string& name) {
  return std::filesystem::path(VDRIG_TEST_DATA_DIR) / "probes" / (name + ".exr");
}

/// Loads a real probe; the test FAILS (not skips) when the file is missing, saying where it was expected.
inline ::testing::AssertionResult load_real_probe(const std::string& name, Probe* out, int width = 0) {
  const auto path = real_probe_path(name);
  if (!std::filesystem::exists(path))
    return ::testing::AssertionFailure() << "real light probe " << path
                                         << " is missing: the test data folder (VDRIG_TEST_DATA_DIR = "
                                         << VDRIG_TEST_DATA_DIR << ") must hold probes/" << name << ".exr";
  LoadOptions options;
  options.width = width;
  auto p = load_probe(path, options);
  if (!p) return ::testing::AssertionFailure() << "loading " << path << ": " << p.error().describe();
  *out = std::move(p.value());
  return ::testing::AssertionSuccess();
}

/// A map whose pixel (i, j) holds f(direction through the pixel centre).
inline Probe synthetic_probe(int height, const std::function<Rgb(const Vec3d&)>& f) {
  Probe p = make_probe(height);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) p.set_pixel(i, j, f(latlong_direction(i, j, p.width(), p.height())));
  return p;
}

/// The same map as a median cut or SH projection that forgot the solid angle would see it: every pixel weighted
/// by the mean pixel solid angle 4 pi / (W H) instead of its row's. Feeding this to a correct implementation
/// reproduces the bug exactly, so tests can show that their error bounds catch it.
inline Probe without_solid_angle_weighting(const Probe& p) {
  Probe q = p;
  q.radiance = p.radiance.clone();
  const double mean = 4.0 * kPi / (static_cast<double>(p.width()) * p.height());
  for (int j = 0; j < p.height(); ++j) {
    const float s = static_cast<float>(mean / latlong_pixel_solid_angle(j, p.width(), p.height()));
    for (int i = 0; i < p.width(); ++i) q.radiance.at<cv::Vec3f>(j, i) *= s;
  }
  return q;
}

}  // namespace vdrig::probe::testing

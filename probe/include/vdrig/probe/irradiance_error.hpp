// How far an irradiance approximation (median-cut lights, SH-9, a reduced map) is from brute-force integration over
// the full map: the measure of the probe tests, bench_probe_lights and docs/probe.md's accuracy tables.
#pragma once

#include <functional>
#include <vector>

#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

/// Relative errors of the luminance irradiance over a set of normals: per normal |E - E_ref| / E_ref, its mean and
/// max, and of_mean = mean |E - E_ref| / mean E_ref (dim normals weigh less).
struct IrradianceErrorStats {
  double mean = 0, max = 0, of_mean = 0;
};

/// Brute-force E(n) (IrradianceIntegrator over the full map) at every normal, in order.
std::vector<Rgb> reference_irradiance(const Probe& probe, const std::vector<Vec3d>& normals);

/// The errors of `approx` against `reference` (reference[k] belongs to normals[k]; the sizes must match and every
/// reference luminance must be > 0, both VDRIG_CHECKed).
IrradianceErrorStats irradiance_error(const std::vector<Vec3d>& normals, const std::function<Rgb(const Vec3d&)>& approx,
                                      const std::vector<Rgb>& reference);

}  // namespace vdrig::probe

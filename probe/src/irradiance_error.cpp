#include "vdrig/probe/irradiance_error.hpp"

#include <algorithm>
#include <cmath>

namespace vdrig::probe {

std::vector<Rgb> reference_irradiance(const Probe& probe, const std::vector<Vec3d>& normals) {
  const IrradianceIntegrator brute(probe);
  std::vector<Rgb> out;
  out.reserve(normals.size());
  for (const auto& n : normals) out.push_back(brute.irradiance(n));
  return out;
}

IrradianceErrorStats irradiance_error(const std::vector<Vec3d>& normals, const std::function<Rgb(const Vec3d&)>& approx,
                                      const std::vector<Rgb>& reference) {
  VDRIG_CHECK(normals.size() == reference.size(), "one reference irradiance per normal");
  IrradianceErrorStats s;
  double abs_sum = 0, ref_sum = 0;
  for (size_t k = 0; k < normals.size(); ++k) {
    const double ref = luminance(reference[k]);
    VDRIG_CHECK(ref > 0, "reference irradiance must be positive");
    const double abs_err = std::abs(luminance(approx(normals[k])) - ref);
    s.mean += abs_err / ref / normals.size();
    s.max = std::max(s.max, abs_err / ref);
    abs_sum += abs_err;
    ref_sum += ref;
  }
  s.of_mean = ref_sum > 0 ? abs_sum / ref_sum : 0;
  return s;
}

}  // namespace vdrig::probe

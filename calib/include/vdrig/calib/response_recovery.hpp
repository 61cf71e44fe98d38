// Debevec-Malik (SIGGRAPH 1997) recovery of a camera's response curve from a bracket of a static scene.
#pragma once

#include <array>
#include <span>

#include "vdrig/core/frame.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::calib {

struct ResponseRecoveryOptions {
  /// Weight of the smoothness term sum_z (lambda w(z) g''(z))^2 against the data term sum (w(z)(g(z)-lnE-ln t))^2.
  double lambda = 20.0;
  /// Pixels sampled per channel; 0 picks max(256, 4 * 2^bits / (frames - 1)) so the system is well over-determined.
  int samples = 0;
  /// Candidate pixels are taken on a regular grid of at most this many points (single pixels, never averages).
  int max_candidates = 20000;
  /// A candidate whose code drops by more than this fraction of the code range while exposure grows is rejected
  /// (it moved, or it is a defect).
  double monotonic_tolerance = 1.0 / 64.0;
  /// Seed of the spatial shuffle of candidates (determinism).
  unsigned seed = 1;
};

/// The curve plus what the fit saw, for the log and the report. Arrays are indexed like the curve: R, G, B.
struct RecoveredResponse {
  ResponseCurve curve;
  std::array<int, 3> samples{};              // pixels used per channel
  std::array<double, 3> rms_residual_log{};  // RMS of w-weighted g(z) - ln E - ln t over the data rows, per channel
};

/// Solves, per channel, for g(z) = ln inverse(z) and the log radiance ln E_i of the sampled pixels, minimising
///   sum_ij [w(z_ij) (g(z_ij) - ln E_i - ln t_j)]^2 + lambda^2 sum_z [w(z) (g(z-1) - 2 g(z) + g(z+1))]^2,
/// with w the hat weight (zero at the clipped codes 0 and max), t_j = exposure_s * gain. Sparse normal equations
/// (Eigen SimplicialLDLT); the gauge g(mid) = 0 is fixed in the solve.
///
/// Samples: single pixels on a regular grid, shuffled, each kept only if its codes do not decrease with exposure
/// and at least two exposures see it unclipped; they are chosen round-robin over the frames and over bins of code
/// value so that the code range is covered evenly (not just the common mid-tones).
///
/// The result is made monotonic (non-decreasing) and scaled: the channels share inverse(mid code) (a bracket cannot
/// see channel gains, so a pixel at mid code in all channels is taken as neutral), and the common factor puts
/// saturation at X = 1 (core's convention) on average over the channels, leaving the mid code near the 0.1..0.3 of a
/// typical camera. Saturation is estimated by extending g linearly from codes 70..90 % of the range to max_code:
/// the top codes themselves are poorly determined (few observations, biased by clipping with noise), so the stored
/// inverse at the last few codes may differ from that estimate (docs/calib.md gives by how much).
/// Needs at least two frames (validate_bracket's errors otherwise), and bits <= 12 (kUnsupported above: such
/// cameras are raw/linear, use ResponseCurve::linear).
Result<RecoveredResponse> recover_response(std::span<const Frame> frames, const ResponseRecoveryOptions& options = {});

}  // namespace vdrig::calib

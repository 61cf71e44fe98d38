#include "vdrig/calib/response_recovery.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::calib {

namespace {

int code_at(const cv::Mat& img, int y, int x, int c) {
  if (img.depth() == CV_8U) return img.ptr<uint8_t>(y)[x * 3 + c];
  return img.ptr<uint16_t>(y)[x * 3 + c];
}

}  // namespace

Result<RecoveredResponse> recover_response(std::span<const Frame> frames, const ResponseRecoveryOptions& opt) {
  VDRIG_TRY(validate_bracket(frames, ResponseCurve{}, 2));
  const int bits = frames[0].bits;
  if (bits > 12)
    return make_error(ErrorCode::kUnsupported, std::to_string(bits) +
                                                   "-bit codes: recover a response only for <= 12-bit (processed) "
                                                   "output; raw sensors are linear (ResponseCurve::linear)");
  if (!(opt.lambda >= 0)) return make_error(ErrorCode::kInvalidArgument, "lambda must be >= 0");
  auto log = log::get("calib");
  const int n = 1 << bits, max_code = n - 1;
  const size_t P = frames.size();

  // Exposure order (the bracket may be given longest first).
  std::vector<size_t> order(P);
  std::iota(order.begin(), order.end(), size_t{0});
  std::vector<double> log_t(P);
  for (size_t j = 0; j < P; ++j) log_t[j] = std::log(frames[j].exposure_s * frames[j].gain);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return log_t[a] < log_t[b]; });

  // Candidate pixels on a regular grid, shuffled so that any prefix is spread over the image.
  const int W = frames[0].image.cols, H = frames[0].image.rows;
  const int step = std::max(1, static_cast<int>(std::ceil(std::sqrt(double(W) * H / std::max(1, opt.max_candidates)))));
  std::vector<cv::Point> candidates;
  for (int y = step / 2; y < H; y += step)
    for (int x = step / 2; x < W; x += step) candidates.emplace_back(x, y);
  std::mt19937 rng(opt.seed);
  std::shuffle(candidates.begin(), candidates.end(), rng);

  const int wanted =
      opt.samples > 0 ? opt.samples : std::max(256, static_cast<int>(4 * n / std::max<size_t>(1, P - 1)));
  const int bins = std::min(n - 2, 256);
  const int tol = static_cast<int>(std::lround(opt.monotonic_tolerance * max_code));
  std::vector<double> w(static_cast<size_t>(n));
  for (int z = 0; z < n; ++z) w[static_cast<size_t>(z)] = hdr_hat_weight(z, max_code);

  RecoveredResponse out;
  std::array<std::vector<double>, 3> inverse, logs;
  for (int c = 0; c < 3; ++c) {  // image channel c (B, G, R) -> response channel rc (R, G, B)
    const size_t rc = static_cast<size_t>(2 - c);
    // Codes of each usable candidate, in exposure order.
    std::vector<std::vector<int>> codes;
    codes.reserve(candidates.size());
    std::vector<int> z(P);
    for (const auto& p : candidates) {
      int unclipped = 0;
      bool monotonic = true;
      for (size_t k = 0; k < P; ++k) {
        z[k] = code_at(frames[order[k]].image, p.y, p.x, c);
        if (z[k] > 0 && z[k] < max_code) ++unclipped;
        if (k > 0 && z[k] < z[k - 1] - tol) monotonic = false;
      }
      if (monotonic && unclipped >= 2) codes.push_back(z);
    }
    if (codes.empty())
      return make_error(ErrorCode::kInvalidArgument,
                        std::string("channel ") + "RGB"[rc] +
                            ": no pixel is seen unclipped in two exposures (bracket too wide, or scene too flat)");

    // Buckets per (frame, code bin); pick round-robin over bins and frames until enough samples are taken.
    std::vector<std::vector<size_t>> bucket(P * static_cast<size_t>(bins));
    for (size_t i = 0; i < codes.size(); ++i)
      for (size_t k = 0; k < P; ++k) {
        const int zz = codes[i][k];
        if (zz <= 0 || zz >= max_code) continue;
        const int b = std::min(bins - 1, (zz - 1) * bins / (max_code - 1));
        bucket[k * static_cast<size_t>(bins) + static_cast<size_t>(b)].push_back(i);
      }
    std::vector<char> taken(codes.size(), 0);
    std::vector<size_t> cursor(bucket.size(), 0);
    std::vector<size_t> chosen;
    for (bool progress = true; progress && static_cast<int>(chosen.size()) < wanted;) {
      progress = false;
      for (int b = 0; b < bins && static_cast<int>(chosen.size()) < wanted; ++b)
        for (size_t k = 0; k < P && static_cast<int>(chosen.size()) < wanted; ++k) {
          auto& bk = bucket[k * static_cast<size_t>(bins) + static_cast<size_t>(b)];
          auto& cur = cursor[k * static_cast<size_t>(bins) + static_cast<size_t>(b)];
          while (cur < bk.size() && taken[bk[cur]]) ++cur;
          if (cur < bk.size()) {
            taken[bk[cur]] = 1;
            chosen.push_back(bk[cur]);
            progress = true;
          }
        }
    }
    const size_t N = chosen.size();

    // Least squares A x = b, x = [g(0..n-1), lnE(0..N-1)].
    using Triplet = Eigen::Triplet<double>;
    std::vector<Triplet> trip;
    std::vector<double> rhs;
    int row = 0;
    for (size_t i = 0; i < N; ++i)
      for (size_t k = 0; k < P; ++k) {
        const int zz = codes[chosen[i]][k];
        const double wz = w[static_cast<size_t>(zz)];
        if (wz <= 0) continue;
        trip.emplace_back(row, zz, wz);
        trip.emplace_back(row, n + static_cast<int>(i), -wz);
        rhs.push_back(wz * log_t[order[k]]);
        ++row;
      }
    const int data_rows = row;
    for (int zz = 1; zz < n - 1; ++zz) {
      const double s = opt.lambda * w[static_cast<size_t>(zz)];
      trip.emplace_back(row, zz - 1, s);
      trip.emplace_back(row, zz, -2 * s);
      trip.emplace_back(row, zz + 1, s);
      rhs.push_back(0);
      ++row;
    }
    trip.emplace_back(row, n / 2, 1.0);  // gauge: g(mid) = 0
    rhs.push_back(0);
    ++row;

    const int cols = n + static_cast<int>(N);
    Eigen::SparseMatrix<double> A(row, cols);
    A.setFromTriplets(trip.begin(), trip.end());
    const Eigen::Map<const Eigen::VectorXd> b(rhs.data(), static_cast<Eigen::Index>(rhs.size()));
    const Eigen::SparseMatrix<double> AtA = A.transpose() * A;
    const Eigen::VectorXd Atb = A.transpose() * b;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(AtA);
    if (solver.info() != Eigen::Success)
      return make_error(ErrorCode::kInternal,
                        std::string("response solve failed to factorise (channel ") + "RGB"[rc] + ")");
    const Eigen::VectorXd x = solver.solve(Atb);
    if (solver.info() != Eigen::Success || !x.allFinite())
      return make_error(ErrorCode::kInternal, std::string("response solve failed (channel ") + "RGB"[rc] + ")");
    const Eigen::VectorXd r = (A * x - b).head(data_rows);
    out.rms_residual_log[rc] = data_rows ? std::sqrt(r.squaredNorm() / data_rows) : 0.0;
    out.samples[rc] = static_cast<int>(N);

    // Monotonic outward from the well-determined middle (g(mid) = 0 from the gauge row).
    auto& g = logs[rc];
    g.assign(x.data(), x.data() + n);
    for (size_t zz = static_cast<size_t>(n / 2 + 1); zz < static_cast<size_t>(n); ++zz)
      g[zz] = std::max(g[zz], g[zz - 1]);
    for (int zz = n / 2 - 1; zz >= 0; --zz)
      g[static_cast<size_t>(zz)] = std::min(g[static_cast<size_t>(zz)], g[static_cast<size_t>(zz) + 1]);
    log->debug("response channel {}: {} samples, {} data rows, rms log residual {:.4f}", "RGB"[rc], N, data_rows,
               out.rms_residual_log[rc]);
  }
  // Scale. A bracket fixes each channel's curve only up to its own factor (channel gains are invisible to it), so
  // the channels are tied at the best-determined code, mid (a pixel at mid code in every channel stays neutral),
  // and one common factor puts saturation at X = 1 (core's convention) on average over the channels.
  // Tying the channels at the extrapolated top code instead would tint the result by its noise.
  // g at the top codes themselves rests on few, clip-biased observations (a noisy code near max is as likely to be
  // clipped away as kept), so the top is a straight-line extrapolation of g over codes 70..90 % of the range.
  double top = 0;
  const int z0 = static_cast<int>(0.7 * max_code), z1 = static_cast<int>(0.9 * max_code);
  for (const auto& g : logs) {
    const double slope = (g[static_cast<size_t>(z1)] - g[static_cast<size_t>(z0)]) / (z1 - z0);
    top += (g[static_cast<size_t>(z1)] + slope * (max_code - z1)) / 3.0;
  }
  for (size_t c = 0; c < 3; ++c) {
    inverse[c].resize(static_cast<size_t>(n));
    for (size_t zz = 0; zz < static_cast<size_t>(n); ++zz) inverse[c][zz] = std::exp(logs[c][zz] - top);
  }
  auto curve = ResponseCurve::from_inverse(bits, std::move(inverse));
  if (!curve) return curve.error();
  out.curve = std::move(*curve);
  return out;
}

}  // namespace vdrig::calib

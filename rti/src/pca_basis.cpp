#include "vdrig/rti/pca_basis.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <thread>

#include "jpeg_444.hpp"
#include "stack_reader.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/sh.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;
using Eigen::MatrixXd;
using Eigen::VectorXd;

Error invalid(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }

// IEC 61966-2-1, the curve the default import inverted: display value of a linear radiance.
double srgb_encode(double v) {
  v = std::clamp(v, 0.0, 1.0);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

double display_value(float radiance, DisplayEncoding encoding) {
  return encoding == DisplayEncoding::kSrgb ? srgb_encode(radiance) : std::clamp(double(radiance), 0.0, 1.0);
}

/// Runs body(item) for items 0..count-1 on `threads` workers; the first failure stops the rest and is returned.
Status parallel_for(int count, int threads, const std::function<Status(int item, int worker)>& body) {
  std::atomic<int> next{0};
  std::mutex mutex;
  Status first = Status::ok();
  auto work = [&](int worker) {
    for (int item; (item = next++) < count;) {
      Status s = body(item, worker);
      if (!s) {
        std::lock_guard lock(mutex);
        if (first) first = s;
        next = count;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int w = 1; w < threads; ++w) pool.emplace_back(work, w);
  work(0);
  for (auto& t : pool) t.join();
  return first;
}

/// Training views' display values of texel (s, t): 3 per view (light-major, R G B).
void texel_values(const fitting::ObsTile& tile, int s, int t, const std::vector<int>& views, DisplayEncoding encoding,
                  float* out) {
  Eigen::Vector3f rgb, dir;
  for (size_t i = 0; i < views.size(); ++i) {
    // Every flag is used: an RTI import flags nothing but clipped pixels, whose codes are still the best value
    // the viewer can be asked to show (the fit has no per-texel sample selection, one operator serves all).
    tile.observation(s, t, views[i], &rgb, &dir);
    for (int k = 0; k < 3; ++k) out[3 * i + k] = static_cast<float>(display_value(rgb[k], encoding));
  }
}

using MatrixXf = Eigen::MatrixXf;

/// The sample of texels the PCA sees: a sheared lattice (not whole columns) of about `pca_texels` texels.
bool pca_sample(int s, int t, int64_t step) { return (s + 7 * int64_t(t)) % step == 0; }

/// The stack's texels, a block at a time, for the two passes of the fit (covariance, coefficients): body(worker, y,
/// s, t) gets y (D x m, D = 3 x lights: column j is texel (s[j], t[j]), row 3 i + k its display value under light i
/// in channel k) from up to `threads` workers at once, each with its own `worker` index.
class TexelBlocks {
 public:
  using Body = std::function<void(int worker, const Eigen::Ref<const MatrixXf>& y, const std::vector<int>& s,
                                  const std::vector<int>& t)>;
  virtual ~TexelBlocks() = default;
  /// Every texel (step 0) or only those of pca_sample(step); `stage` names the pass for the progress callback.
  virtual Status for_each(int64_t step, const std::string& stage, const Body& body) = 0;
};

/// An observation map (vdrig rti import), tile by tile on `threads` workers.
class ObsMapBlocks final : public TexelBlocks {
 public:
  ObsMapBlocks(const fitting::ObsMapReader& obs, std::vector<int> views, DisplayEncoding encoding, int threads,
               const RbfFitOptions& options)
      : obs_(obs), views_(std::move(views)), encoding_(encoding), threads_(threads), options_(options) {}

  Status for_each(int64_t step, const std::string& stage, const Body& body) override {
    const int tiles = obs_.tiles_s() * obs_.tiles_t(), D = 3 * static_cast<int>(views_.size());
    std::atomic<int> done{0};
    return parallel_for(tiles, threads_, [&](int item, int worker) -> Status {
      auto tile = obs_.read_tile(item % obs_.tiles_s(), item / obs_.tiles_s());
      if (!tile) return tile.error();
      std::vector<int> s, t;
      for (int tt = tile->t0(); tt < tile->t0() + tile->height(); ++tt)
        for (int ss = tile->s0(); ss < tile->s0() + tile->width(); ++ss)
          if (step == 0 || pca_sample(ss, tt, step)) {
            s.push_back(ss);
            t.push_back(tt);
          }
      MatrixXf y(D, static_cast<Eigen::Index>(s.size()));
      for (size_t j = 0; j < s.size(); ++j)
        texel_values(tile.value(), s[j], t[j], views_, encoding_, y.col(static_cast<Eigen::Index>(j)).data());
      body(worker, y, s, t);
      if (options_.on_progress) options_.on_progress(stage, ++done, tiles);
      return Status::ok();
    });
  }

 private:
  const fitting::ObsMapReader& obs_;
  std::vector<int> views_;
  DisplayEncoding encoding_;
  int threads_;
  const RbfFitOptions& options_;
};

/// A stack of photographs (stack_reader.hpp), read from the top a band of rows at a time, each band's images decoded
/// on every thread and its texels then split between the threads. Every pass opens the images again: the stack is
/// decoded twice rather than held in memory (289 images of 1024 x 1024 would be 900 MB as bytes).
class StackBlocks final : public TexelBlocks {
 public:
  StackBlocks(const StackList& list, std::vector<int> views, int threads, const RbfFitOptions& options)
      : list_(list), views_(std::move(views)), threads_(threads), options_(options) {}

  Status for_each(int64_t step, const std::string& stage, const Body& body) override {
    // The codes are the display values (codes / 255 or / 65535); float images pass unchanged, clamped to 0..1.
    auto opened = StackRows::open(list_, views_, Linearisation{}, std::nullopt);
    if (!opened) return opened.error();
    StackRows& rows_in = opened.value();
    const int W = rows_in.width(), H = rows_in.height(), D = 3 * rows_in.images();
    const int band_rows = std::clamp(1024 / W, 1, H);
    MatrixXf band(D, static_cast<Eigen::Index>(band_rows) * W), picked;
    for (int y0 = 0; y0 < H; y0 += band_rows) {
      const int rows = std::min(band_rows, H - y0);
      // Image j's texel x, channel c at band(3 j + c, x): the column of a texel is its D values.
      VDRIG_TRY(rows_in.read_rows(rows, band.data(), 3, D, threads_));
      auto y = band.leftCols(static_cast<Eigen::Index>(rows) * W);
      y = y.cwiseMax(0.0f).cwiseMin(1.0f);
      std::vector<int> s, t, columns;
      for (int r = 0; r < rows; ++r)
        for (int x = 0; x < W; ++x)
          if (step == 0 || pca_sample(x, H - 1 - (y0 + r), step)) {
            s.push_back(x);
            t.push_back(H - 1 - (y0 + r));  // texel rows grow with y, up in the image (import.hpp)
            columns.push_back(r * W + x);
          }
      if (step != 0) {  // the sampled columns, gathered
        picked.resize(D, static_cast<Eigen::Index>(columns.size()));
        for (size_t j = 0; j < columns.size(); ++j) picked.col(static_cast<Eigen::Index>(j)) = y.col(columns[j]);
      }
      const MatrixXf& texels = step != 0 ? picked : band;
      const int m = static_cast<int>(s.size());
      parallel_for_strided(threads_, threads_, [&](int w) {
        const int first = m * w / threads_, last = m * (w + 1) / threads_;
        if (first == last) return;
        const std::vector<int> ws(s.begin() + first, s.begin() + last), wt(t.begin() + first, t.begin() + last);
        body(w, texels.middleCols(first, last - first), ws, wt);
      });
      if (options_.on_progress) options_.on_progress(stage, y0 + rows, H);
    }
    return Status::ok();
  }

 private:
  const StackList& list_;
  std::vector<int> views_;
  int threads_;
  const RbfFitOptions& options_;
};

uint8_t to_byte(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

}  // namespace

Result<DisplayEncoding> parse_display_encoding(const std::string& text) {
  if (text == "srgb" || text == "sRGB") return DisplayEncoding::kSrgb;
  if (text == "codes" || text == "linear") return DisplayEncoding::kCodes;
  return invalid("display encoding \"" + text +
                 "\": expected codes (the stack's values are codes / 255) or srgb (imported with --response sRGB)");
}

double RbfBasis::table(int p, int i, int k) const {
  const double byte = basis[(static_cast<size_t>(p) * lights.size() + static_cast<size_t>(i)) * 3 + k];
  return p == 0 ? byte / 255.0 : (byte - 127.0) / range[static_cast<size_t>(p - 1)];
}

double openlime_epsilon(const std::vector<Vec3d>& lights, const Vec3d& light) {
  // openlime.js AdaptiveRBF(samples, alpha = 8, k = 24), beta = 2; k is unused there: every light takes part.
  // The width adapts to how far the lights are: eps = alpha / (Σ d e^(-beta d) / Σ e^(-beta d)).
  constexpr double kAlpha = 8.0, kBeta = 2.0;
  double num = 0.0, den = 0.0;
  for (const Vec3d& l : lights) {
    const double d = (l - light).norm();
    num += d * std::exp(-kBeta * d);
    den += std::exp(-kBeta * d);
  }
  return kAlpha / (num / den);
}

std::vector<double> rbf_weights(const std::vector<Vec3d>& lights, const Vec3d& light, RbfWeights kind, double sigma) {
  const size_t n = lights.size();
  std::vector<double> w(n, 0.0), dist(n);
  for (size_t i = 0; i < n; ++i) dist[i] = (lights[i] - light).norm();
  double total = 0.0;
  if (kind == RbfWeights::kOpenLime) {
    const double epsilon = openlime_epsilon(lights, light);
    for (size_t i = 0; i < n; ++i) total += w[i] = std::exp(-epsilon * dist[i] * dist[i]);
    for (double& x : w) x /= total;
    return w;
  }
  // relight src/rti.cpp Rti::lightWeightsRbf: radius 1 / sigma^2, normalise, drop weights <= 0.001, renormalise.
  const double radius = 1.0 / (sigma * sigma);
  for (size_t i = 0; i < n; ++i) total += w[i] = std::exp(-radius * dist[i] * dist[i]);
  double kept = 0.0;
  for (double& x : w) {
    x /= total;
    if (x > 0.001)
      kept += x;
    else
      x = 0.0;
  }
  for (double& x : w) x /= kept;
  return w;
}

std::vector<float> render_rbf(const RbfBasis& b, const Vec3d& light, RbfWeights kind) {
  const int n = static_cast<int>(b.lights.size());
  const std::vector<double> w = rbf_weights(b.lights, light, kind, b.sigma);
  // base[p][k] = Σ_i w_i table(p, i, k), as OpenLIME's RBF.lightWeights (uniform `base`).
  std::vector<double> base(static_cast<size_t>(b.planes + 1) * 3, 0.0);
  for (int p = 0; p <= b.planes; ++p)
    for (int i = 0; i < n; ++i)
      if (w[static_cast<size_t>(i)] != 0.0)
        for (int k = 0; k < 3; ++k)
          base[static_cast<size_t>(3 * p + k)] += w[static_cast<size_t>(i)] * b.table(p, i, k);
  const size_t texels = static_cast<size_t>(b.width) * b.height;
  std::vector<float> out(texels * 3);
  for (size_t x = 0; x < texels; ++x) {
    double rgb[3] = {base[0], base[1], base[2]};
    for (int p = 0; p < b.planes; ++p) {
      const size_t pp = static_cast<size_t>(p);
      const double c = (b.coefficient_bytes[pp][x] / 255.0 - b.bias[pp]) * b.scale[pp];
      for (int k = 0; k < 3; ++k) rgb[k] += base[static_cast<size_t>(3 * (p + 1) + k)] * c;
    }
    for (int k = 0; k < 3; ++k) {
      double code = 255.0 * rgb[k];
      if (kind == RbfWeights::kRelightCli) code = std::trunc(code);  // relight's (int) casts
      out[3 * x + static_cast<size_t>(k)] = static_cast<float>(std::clamp(code, 0.0, 255.0));
    }
  }
  return out;
}

namespace {

Status check_rbf_options(const RbfFitOptions& options) {
  const int P = options.planes;
  if (P < 3 || P > 48 || P % 3 != 0)
    return invalid("rbf planes " + std::to_string(P) + ": a multiple of 3 from 3 to 48 (OpenLIME reads 3 per JPEG)");
  if (options.jpeg_quality < 1 || options.jpeg_quality > 100)
    return invalid("JPEG quality " + std::to_string(options.jpeg_quality) + ": expected 1..100");
  return Status::ok();
}

/// Views 0..views-1 without the held-out ones; kInvalidArgument for a held-out view outside them or too few left.
Result<std::vector<int>> training_views(int views, const RbfFitOptions& options) {
  std::set<int> held(options.held_out.begin(), options.held_out.end());
  for (int v : held)
    if (v < 0 || v >= views)
      return invalid("held-out view " + std::to_string(v) + " outside the map's 0.." + std::to_string(views - 1));
  std::vector<int> train;
  for (int v = 0; v < views; ++v)
    if (!held.count(v)) train.push_back(v);
  const int N = static_cast<int>(train.size());
  if (N < options.planes + 1)
    return invalid(std::to_string(N) + " lights cannot carry " + std::to_string(options.planes) +
                   " planes (need planes + 1)");
  return train;
}

int worker_count(const RbfFitOptions& options) {
  return std::clamp(options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency()), 1,
                    64);
}

/// The fit (pca_basis.hpp) of S x T texels seen through `blocks` under `lights` (unit, the training views').
Result<RbfBasis> fit_rbf(TexelBlocks& blocks, int S, int T, std::vector<Vec3d> lights, const RbfFitOptions& options) {
  const int P = options.planes, N = static_cast<int>(lights.size()), D = 3 * N;
  const int threads = worker_count(options);
  auto progress = [&](const std::string& stage, int done, int total) {
    if (options.on_progress) options.on_progress(stage, done, total);
  };
  RbfBasis out;
  out.width = S;
  out.height = T;
  out.planes = P;
  out.jpeg_quality = options.jpeg_quality;
  out.lights = std::move(lights);

  // 1. PCA of the display values over a subsample of texels: sums of y and (y - 1/2)(y - 1/2)^T per worker, in
  // single precision (twice the speed of double in the matrix product; the shift by 1/2, mid-range, keeps the
  // centring's cancellation small, and 8-bit values need no more).
  const int64_t step = std::max<int64_t>(1, int64_t(S) * T / std::max(1, options.pca_texels));
  std::vector<MatrixXf> cov(static_cast<size_t>(threads));
  std::vector<VectorXd> sum(static_cast<size_t>(threads), VectorXd::Zero(D));
  std::vector<int64_t> count(static_cast<size_t>(threads), 0);
  VDRIG_TRY(blocks.for_each(step, "covariance",
                            [&](int worker, const Eigen::Ref<const MatrixXf>& y, const std::vector<int>& /*s*/,
                                const std::vector<int>& /*t*/) {
                              const size_t w = static_cast<size_t>(worker);
                              if (cov[w].size() == 0) cov[w] = MatrixXf::Zero(D, D);
                              const MatrixXf shifted = y.array() - 0.5f;
                              cov[w].selfadjointView<Eigen::Lower>().rankUpdate(shifted);
                              sum[w] += y.cast<double>().rowwise().sum();
                              count[w] += y.cols();
                            }));
  MatrixXd C = MatrixXd::Zero(D, D);
  for (size_t w = 0; w < cov.size(); ++w) {
    if (cov[w].size() != 0) C += cov[w].cast<double>();
    if (w > 0) {
      sum[0] += sum[w];
      count[0] += count[w];
    }
  }
  cov.clear();
  if (count[0] == 0) return invalid("no texels to fit");
  const double n = static_cast<double>(count[0]);
  const VectorXd mean = sum[0] / n, shift = mean.array() - 0.5;
  C = C.selfadjointView<Eigen::Lower>();
  C = (C - n * shift * shift.transpose()) / n;
  progress("eigenvectors", 0, 1);
  // Only the P leading eigenvectors are needed: subspace iteration on P + 8 vectors costs D^2 (P + 8) per step
  // instead of the full decomposition's ~10 D^3 (867 x 867 at 289 lights: ~0.1 s instead of ~1.5 s). RTI stacks
  // have a steep spectrum (9 planes keep > 99.9% of the variance), so a few dozen steps converge.
  const int k = std::min(D, P + 8);
  MatrixXd Q = MatrixXd::Zero(D, k);
  for (int j = 0; j < k; ++j)  // deterministic start: spread unit vectors plus a ramp, so no column is orthogonal
    for (int r = 0; r < D; ++r) Q(r, j) = (r % k == j ? 1.0 : 0.0) + 1e-3 * std::cos(0.37 * (r + 1) * (j + 1));
  for (int step = 0; step < 40; ++step) {
    const MatrixXd CQ = C * Q;
    Q = Eigen::HouseholderQR<MatrixXd>(CQ).householderQ() * MatrixXd::Identity(D, k);
  }
  Eigen::SelfAdjointEigenSolver<MatrixXd> small(Q.transpose() * C * Q);  // Rayleigh-Ritz
  if (small.info() != Eigen::Success) return make_error(ErrorCode::kInternal, "PCA eigen-decomposition failed");
  MatrixXd E(D, P);  // leading eigenvectors first (the solver sorts ascending)
  for (int p = 0; p < P; ++p) E.col(p) = Q * small.eigenvectors().col(k - 1 - p);
  double kept = 0.0, total = C.trace();
  for (int p = 0; p < P; ++p) kept += small.eigenvalues()(k - 1 - p);
  log::get("rti")->info("rbf: PCA of {} texels x {} lights, {} planes keep {:.4f} of the variance", count[0], N, P,
                        total > 0 ? kept / total : 1.0);

  // 2. The table: W(j, i) = OpenLIME's weight of light i when rendering at light j. Deconvolve so that W times the
  // table is the eigenvectors (and the mean) at the lights.
  MatrixXd W(N, N);
  double mean_epsilon = 0.0;
  for (int j = 0; j < N; ++j) {
    mean_epsilon += openlime_epsilon(out.lights, out.lights[static_cast<size_t>(j)]) / N;
    const std::vector<double> w = rbf_weights(out.lights, out.lights[static_cast<size_t>(j)], RbfWeights::kOpenLime);
    for (int i = 0; i < N; ++i) W(j, i) = w[static_cast<size_t>(i)];
  }
  // relight's own renderers (relight-cli -L, relight's web viewer) use exp(-d^2 / sigma^2) instead: this sigma
  // gives them about the width OpenLIME uses, so they show nearly what OpenLIME shows.
  out.sigma = 1.0 / std::sqrt(mean_epsilon);
  // Column p of `table` is plane p (p = 0 the mean), rows (light i, channel k) at 3 i + k.
  MatrixXd table(D, P + 1);
  table.col(0) = mean;
  table.rightCols(P) = E;
  if (options.deconvolution >= 0) {
    const MatrixXd normal = W.transpose() * W + options.deconvolution * MatrixXd::Identity(N, N);
    const Eigen::LDLT<MatrixXd> solver(normal);
    for (int p = 0; p <= P; ++p) {
      // The column as N x 3 (light x channel): the interpolation acts on each channel alike.
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> m(table.col(p).data(), N, 3);
      const MatrixXd solved = solver.solve(W.transpose() * MatrixXd(m));
      m = solved;
    }
  }
  // 3. Quantise as the file holds it: the mean as byte / 255, basis p as 127 + range_p x (bytes 0..254).
  out.basis.resize(static_cast<size_t>(P + 1) * D);
  out.range.resize(static_cast<size_t>(P));
  for (int p = 0; p <= P; ++p) {
    double scale = 255.0;
    if (p > 0) {
      const double peak = std::max(table.col(p).cwiseAbs().maxCoeff(), 1e-12);
      out.range[static_cast<size_t>(p - 1)] = scale = 127.0 / peak;
    }
    for (int r = 0; r < D; ++r)
      out.basis[static_cast<size_t>(p) * D + r] = to_byte(p == 0 ? scale * table(r, p) : 127.0 + scale * table(r, p));
  }
  // 4. Coefficients: least squares against what the viewer renders at the lights from the quantised table,
  // y ≈ b + A c with A = (W ⊗ I3) table_q, b its mean column.
  MatrixXd Tq(D, P + 1);
  for (int p = 0; p <= P; ++p)
    for (int i = 0; i < N; ++i)
      for (int k = 0; k < 3; ++k) Tq(3 * i + k, p) = out.table(p, i, k);
  MatrixXd R(D, P + 1);
  for (int p = 0; p <= P; ++p) {
    Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> m(Tq.col(p).data(), N, 3);
    const MatrixXd r = W * m;
    for (int i = 0; i < N; ++i)
      for (int k = 0; k < 3; ++k) R(3 * i + k, p) = r(i, k);
  }
  const VectorXd b = R.col(0);
  const MatrixXd A = R.rightCols(P);
  const MatrixXd G = (A.transpose() * A).ldlt().solve(A.transpose());  // P x D
  const Eigen::MatrixXf Gf = G.cast<float>();
  const Eigen::VectorXf Gb = (G * b).cast<float>();
  std::vector<std::vector<float>> coeff(static_cast<size_t>(P), std::vector<float>(static_cast<size_t>(S) * T));
  VDRIG_TRY(blocks.for_each(
      0, "coefficients",
      [&](int /*worker*/, const Eigen::Ref<const MatrixXf>& y, const std::vector<int>& s, const std::vector<int>& t) {
        MatrixXf c = Gf * y;
        c.colwise() -= Gb;
        for (size_t j = 0; j < s.size(); ++j) {
          const size_t at = static_cast<size_t>(T - 1 - t[j]) * S + static_cast<size_t>(s[j]);
          for (int p = 0; p < P; ++p) coeff[static_cast<size_t>(p)][at] = c(p, static_cast<Eigen::Index>(j));
        }
      }));
  // 5. Coefficient planes: the full range of each (relight clips at the 99.5% quantile; a clipped texel is wrong
  // under every light, one step more of quantisation costs a fraction of a code), through the JPEG encoder.
  out.scale.resize(static_cast<size_t>(P));
  out.bias.resize(static_cast<size_t>(P));
  out.coefficient_bytes.assign(static_cast<size_t>(P), std::vector<uint8_t>(static_cast<size_t>(S) * T));
  for (int j = 0; j < P / 3; ++j) {
    cv::Mat bgr(T, S, CV_8UC3);
    for (int ch = 0; ch < 3; ++ch) {
      const auto& c = coeff[static_cast<size_t>(3 * j + ch)];
      const auto [lo, hi] = std::minmax_element(c.begin(), c.end());
      const double span = std::max(double(*hi) - *lo, 1e-12);
      out.scale[static_cast<size_t>(3 * j + ch)] = span;
      out.bias[static_cast<size_t>(3 * j + ch)] = -*lo / span;
      for (int y = 0; y < T; ++y)
        for (int x = 0; x < S; ++x)
          bgr.at<cv::Vec3b>(y, x)[2 - ch] = to_byte((c[static_cast<size_t>(y) * S + x] - *lo) / span * 255.0);
    }
    auto jpeg = encode_jpeg_444(bgr, options.jpeg_quality);
    if (!jpeg) return jpeg.error();
    auto decoding = decode_image(jpeg.value(), "plane JPEG " + std::to_string(j), ImageDecode::kBgr8);
    if (!decoding) return make_error(ErrorCode::kInternal, decoding.error().message);
    const cv::Mat decoded = std::move(decoding.value());
    if (decoded.rows != T || decoded.cols != S)
      return make_error(ErrorCode::kInternal, "plane JPEG " + std::to_string(j) + " does not decode to its size");
    for (int ch = 0; ch < 3; ++ch)
      for (int y = 0; y < T; ++y)
        for (int x = 0; x < S; ++x)
          out.coefficient_bytes[static_cast<size_t>(3 * j + ch)][static_cast<size_t>(y) * S + x] =
              decoded.at<cv::Vec3b>(y, x)[2 - ch];
    out.plane_jpeg.push_back(std::move(jpeg.value()));
  }
  return out;
}

}  // namespace

Result<RbfBasis> fit_rbf_basis(const fitting::ObsMapReader& obs, const RbfFitOptions& options) {
  VDRIG_TRY(check_rbf_options(options));
  auto train = training_views(obs.views(), options);
  if (!train) return train.error();
  std::vector<Vec3d> lights;
  {  // the lights: every texel of an RTI map sees view v from the same direction
    auto tile = obs.read_tile(0, 0);
    if (!tile) return tile.error();
    Eigen::Vector3f rgb, dir;
    for (int v : train.value()) {
      tile->observation(tile->s0(), tile->t0(), v, &rgb, &dir);
      lights.push_back(dir.cast<double>().normalized());
    }
  }
  ObsMapBlocks blocks(obs, train.value(), options.encoding, worker_count(options), options);
  return fit_rbf(blocks, obs.spec().texels_s, obs.spec().texels_t, std::move(lights), options);
}

Result<RbfBasis> fit_rbf_basis(const fs::path& stack, const RbfFitOptions& options) {
  VDRIG_TRY(check_rbf_options(options));
  if (options.encoding != DisplayEncoding::kCodes)
    return invalid("--encoding applies to observation maps: a stack's photographs hold the codes themselves");
  auto listed = list_stack(stack);
  if (!listed) return listed.error();
  auto train = training_views(static_cast<int>(listed->lights.size()), options);
  if (!train) return train.error();
  std::vector<Vec3d> lights;
  for (int v : train.value()) lights.push_back(listed->lights[static_cast<size_t>(v)].direction.normalized());
  // The size, from the images themselves (every one is opened, so a size that differs is refused here).
  int S = 0, T = 0;
  {
    auto opened = StackRows::open(listed.value(), train.value(), Linearisation{}, std::nullopt);
    if (!opened) return opened.error();
    S = opened->width();
    T = opened->height();
  }
  StackBlocks blocks(listed.value(), train.value(), worker_count(options), options);
  auto basis = fit_rbf(blocks, S, T, std::move(lights), options);
  if (basis)
    log::get("rti")->info("rbf: fitted {} images of {}x{} from {}", basis->lights.size(), S, T,
                          listed->lp_file.string());
  return basis;
}

Status write_relight_rbf(const RbfBasis& b, const fs::path& out) {
  if (b.planes % 3 != 0 || b.coefficient_bytes.size() != static_cast<size_t>(b.planes))
    return invalid("rbf basis with " + std::to_string(b.planes) + " planes: not a multiple of 3 or planes missing");
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return make_error(ErrorCode::kIo, "creating " + out.string() + ": " + ec.message());
  for (int j = 0; j < b.planes / 3; ++j) {
    std::string jpeg;
    if (static_cast<size_t>(j) < b.plane_jpeg.size()) {
      jpeg = b.plane_jpeg[static_cast<size_t>(j)];
    } else {  // e.g. a basis read from elsewhere and edited: encode its bytes
      cv::Mat bgr(b.height, b.width, CV_8UC3);
      for (int ch = 0; ch < 3; ++ch)
        for (int y = 0; y < b.height; ++y)
          for (int x = 0; x < b.width; ++x)
            bgr.at<cv::Vec3b>(y, x)[2 - ch] =
                b.coefficient_bytes[static_cast<size_t>(3 * j + ch)][static_cast<size_t>(y) * b.width + x];
      auto encoded = encode_jpeg_444(bgr, b.jpeg_quality);
      if (!encoded) return encoded.error();
      jpeg = std::move(encoded.value());
    }
    VDRIG_TRY(write_file_atomic(out / ("plane_" + std::to_string(j) + ".jpg"), jpeg));
  }
  nlohmann::json lights = nlohmann::json::array(), basis = nlohmann::json::array();
  for (const Vec3d& l : b.lights)
    for (int k = 0; k < 3; ++k) lights.push_back(l[k]);
  for (uint8_t v : b.basis) basis.push_back(int(v));
  const nlohmann::json info = {
      {"width", b.width},
      {"height", b.height},
      {"format", "jpg"},
      {"type", "rbf"},
      {"colorspace", "mrgb"},
      {"sigma", b.sigma},
      {"lights", lights},
      {"nplanes", b.planes},
      {"quality", b.jpeg_quality},
      {"basis", basis},
      {"materials", nlohmann::json::array({{{"range", b.range}, {"scale", b.scale}, {"bias", b.bias}}})},
      {"producer", "vdrig"}};
  VDRIG_TRY(write_file_atomic(out / "info.json", info.dump() + "\n"));
  log::get("rti")->info("wrote {} (rbf, {} planes, {} lights)", out.string(), b.planes, b.lights.size());
  return Status::ok();
}

Result<RbfBasis> read_relight_rbf(const fs::path& where) {
  if (!fs::exists(where)) return make_error(ErrorCode::kNotFound, where.string() + " does not exist");
  const fs::path folder = fs::is_directory(where) ? where : where.parent_path();
  const fs::path info_path = folder / "info.json";
  std::ifstream in(info_path);
  if (!in) return make_error(ErrorCode::kNotFound, info_path.string() + " does not exist");
  auto corrupt = [&](const std::string& m) { return make_error(ErrorCode::kCorrupt, info_path.string() + ": " + m); };
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    return corrupt(e.what());
  }
  RbfBasis b;
  try {
    if (j.value("type", "") != "rbf" || j.value("colorspace", "") != "mrgb")
      return make_error(ErrorCode::kUnsupported, info_path.string() + ": type \"" + j.value("type", "") +
                                                     "\", colorspace \"" + j.value("colorspace", "") +
                                                     "\" (only rbf over mrgb is read here)");
    b.width = j.at("width").get<int>();
    b.height = j.at("height").get<int>();
    b.planes = j.at("nplanes").get<int>();
    b.sigma = j.value("sigma", 0.125);
    b.jpeg_quality = j.value("quality", 95);
    const auto lights = j.at("lights").get<std::vector<double>>();
    if (lights.size() % 3 != 0 || lights.empty()) return corrupt("\"lights\" is not a list of x, y, z");
    for (size_t i = 0; i < lights.size(); i += 3) b.lights.emplace_back(lights[i], lights[i + 1], lights[i + 2]);
    for (double v : j.at("basis").get<std::vector<double>>())
      b.basis.push_back(static_cast<uint8_t>(std::clamp(v, 0.0, 255.0)));
    const auto& m = j.at("materials").at(0);
    b.range = m.at("range").get<std::vector<double>>();
    b.scale = m.at("scale").get<std::vector<double>>();
    b.bias = m.at("bias").get<std::vector<double>>();
  } catch (const std::exception& e) {
    return corrupt(e.what());
  }
  const size_t P = static_cast<size_t>(b.planes);
  if (b.planes <= 0 || b.width <= 0 || b.height <= 0) return corrupt("non-positive size or plane count");
  if (b.basis.size() != (P + 1) * b.lights.size() * 3)
    return corrupt("\"basis\" holds " + std::to_string(b.basis.size()) +
                   " numbers, (nplanes + 1) x lights x 3 = " + std::to_string((P + 1) * b.lights.size() * 3));
  if (b.range.size() < P || b.scale.size() < P || b.bias.size() < P)
    return corrupt("materials[0] has fewer range/scale/bias values than nplanes");
  b.coefficient_bytes.assign(P, std::vector<uint8_t>(static_cast<size_t>(b.width) * b.height));
  for (size_t jpeg = 0; 3 * jpeg < P; ++jpeg) {
    const fs::path file = folder / ("plane_" + std::to_string(jpeg) + ".jpg");
    std::ifstream f(file, std::ios::binary);
    if (!f) return make_error(ErrorCode::kNotFound, file.string() + " does not exist");
    std::ostringstream bytes;
    bytes << f.rdbuf();
    b.plane_jpeg.push_back(bytes.str());
    const std::string& s = b.plane_jpeg.back();
    auto decoded = decode_image(s, file.string(), ImageDecode::kBgr8);
    if (!decoded) return decoded.error();
    const cv::Mat bgr = std::move(decoded.value());
    if (bgr.rows != b.height || bgr.cols != b.width)
      return corrupt(file.filename().string() + " does not decode to " + std::to_string(b.width) + "x" +
                     std::to_string(b.height));
    for (size_t ch = 0; ch < 3 && 3 * jpeg + ch < P; ++ch)
      for (int y = 0; y < b.height; ++y)
        for (int x = 0; x < b.width; ++x)
          b.coefficient_bytes[3 * jpeg + ch][static_cast<size_t>(y) * b.width + x] =
              bgr.at<cv::Vec3b>(y, x)[2 - static_cast<int>(ch)];
  }
  return b;
}

}  // namespace vdrig::rti

namespace vdrig::rti {

Result<fitting::ParameterMap> rbf_parameter_map(const RbfBasis& b, const fitting::ModelPtr& model) {
  if (!model->linear_in_shared_directions())
    return invalid(model->name() +
                   " cannot hold an rbf basis here: a model linear in its light directions (hsh:N, "
                   "ptm:rgb, sh-*:N) is fitted to it");
  const int N = static_cast<int>(b.lights.size()), P = b.planes;
  fitting::MapFitOptions fit_options;
  fit_options.model = model;
  VDRIG_TRY(model->check_options(fit_options));
  auto op = model->fit_operator(b.lights, fit_options);
  if (!op) return op.error();
  const int K = op->coeff_count();
  if (N < K)
    return invalid(model->name() + " has " + std::to_string(K) + " coefficients per channel; the basis has only " +
                   std::to_string(N) + " lights");
  // The model's basis Y (N x K) from evaluate() of unit parameters, as stack_fit.cpp: the fit is c = F f, its
  // prediction Y c.
  MatrixXd Y(N, K);
  {
    std::vector<double> unit(static_cast<size_t>(3 * K), 0.0);
    for (int k = 0; k < K; ++k) {
      unit[static_cast<size_t>(k)] = 1.0;
      for (int j = 0; j < N; ++j) Y(j, k) = model->evaluate(unit, b.lights[static_cast<size_t>(j)])[0];
      unit[static_cast<size_t>(k)] = 0.0;
    }
  }
  const MatrixXd& F = op->matrix();
  // What the viewer shows at light j, channel k, is linear in the texel's [1, c_0 .. c_{P-1}]: B_k (N x (P + 1))
  // with B_k(j, p) = Σ_i w_i(l_j) table(p, i, k). So the parameters are M_k [1; c] with M_k = F B_k, and the
  // squared residual [1; c]^T R_k^T R_k [1; c] with R_k = (I - Y F) B_k.
  std::vector<MatrixXd> M(3), Q(3);
  for (int k = 0; k < 3; ++k) {
    MatrixXd B(N, P + 1);
    for (int j = 0; j < N; ++j) {
      const std::vector<double> w = rbf_weights(b.lights, b.lights[static_cast<size_t>(j)], RbfWeights::kOpenLime);
      for (int p = 0; p <= P; ++p) {
        double v = 0.0;
        for (int i = 0; i < N; ++i) v += w[static_cast<size_t>(i)] * b.table(p, i, k);
        B(j, p) = v;
      }
    }
    M[static_cast<size_t>(k)] = F * B;
    const MatrixXd R = B - Y * M[static_cast<size_t>(k)];
    Q[static_cast<size_t>(k)] = R.transpose() * R / N;
  }
  fitting::ParameterMap map(model, b.width, b.height, b.width, b.height);
  VectorXd c(P + 1);
  std::vector<double> parameters(static_cast<size_t>(3 * K));
  std::vector<float> rms_codes;
  rms_codes.reserve(static_cast<size_t>(b.width) * b.height);
  for (int row = 0; row < b.height; ++row)
    for (int s = 0; s < b.width; ++s) {
      const size_t x = static_cast<size_t>(row) * b.width + static_cast<size_t>(s);
      c[0] = 1.0;
      for (int p = 0; p < P; ++p) {
        const size_t pp = static_cast<size_t>(p);
        c[p + 1] = (b.coefficient_bytes[pp][x] / 255.0 - b.bias[pp]) * b.scale[pp];
      }
      fitting::FitQuality q;
      for (int k = 0; k < 3; ++k) {
        const VectorXd params = M[static_cast<size_t>(k)] * c;  // parameters are channel by channel
        for (int j = 0; j < K; ++j) parameters[static_cast<size_t>(k * K + j)] = params[j];
        q.rms[k] = std::sqrt(std::max(0.0, c.dot(Q[static_cast<size_t>(k)] * c)));
      }
      q.samples = N;
      const int t = b.height - 1 - row;  // plane rows from the top: texel row t is image row height - 1 - t
      map.set_parameters(s, t, parameters);
      map.set_quality(s, t, q);
      rms_codes.push_back(static_cast<float>(255.0 * (q.rms[0] + q.rms[1] + q.rms[2]) / 3.0));
    }
  std::nth_element(rms_codes.begin(), rms_codes.begin() + static_cast<long>(rms_codes.size() / 2), rms_codes.end());
  log::get("rti")->info("rbf basis ({} planes, {} lights) as {}: median RMS {:.3f} codes from the rbf at its lights", P,
                        N, model->name(), rms_codes.empty() ? 0.0f : rms_codes[rms_codes.size() / 2]);
  return map;
}

}  // namespace vdrig::rti

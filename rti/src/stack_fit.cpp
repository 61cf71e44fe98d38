#include "vdrig/rti/stack_fit.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <barrier>
#include <memory>
#include <thread>
#include <vector>

#include "stack_reader.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/rti/light_positions.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;
using RowMajorXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Texels fitted per band: the band's samples (images x texels x 3 floats) stay near 1.2 MB per 100 images.
constexpr int kTexelsPerBand = 1024;

}  // namespace

Result<fitting::ParameterMap> fit_stack(const fs::path& stack, const StackFitOptions& options) {
  const fitting::ModelPtr& model = options.model;
  VDRIG_CHECK(model != nullptr, "fit_stack: no model");
  if (!model->linear_in_shared_directions())
    return make_error(ErrorCode::kInvalidArgument,
                      model->name() +
                          " is not one linear fit per direction set: import the stack (vdrig rti import) "
                          "and fit the observation map (vdrig rti fit STACK.vdobs)");
  auto listed = list_stack(stack);
  if (!listed) return listed.error();
  const int n = static_cast<int>(listed->lights.size());

  // The model's operator P (K x N per channel) on the stack's directions, and its basis Y (N x K) from evaluate()
  // of unit parameters: the fit is c = P f, its prediction Y c, its hat matrix H = Y P.
  std::vector<Vec3d> dirs;
  for (const LightPosition& l : listed->lights) dirs.push_back(l.direction);
  fitting::MapFitOptions fit_options = options.fit;
  fit_options.model = model;
  VDRIG_TRY(model->check_options(fit_options));
  auto op = model->fit_operator(dirs, fit_options);
  if (!op) return op.error();
  const int K = op->coeff_count(), P = model->parameter_count();
  VDRIG_CHECK(P == 3 * K && op->sample_count() == n, "fit_stack: operator and parameters disagree");
  if (n < K)
    return make_error(ErrorCode::kInvalidArgument, model->name() + " has " + std::to_string(K) +
                                                       " coefficients per channel; the stack has only " +
                                                       std::to_string(n) + " images");
  Eigen::MatrixXd basis(n, K);
  {
    std::vector<double> unit(static_cast<size_t>(P), 0.0);
    for (int k = 0; k < K; ++k) {
      unit[static_cast<size_t>(k)] = 1.0;  // channel R's coefficient k (parameters are channel by channel)
      for (int j = 0; j < n; ++j) {
        const Vec3d rgb = model->evaluate(unit, dirs[static_cast<size_t>(j)]);
        VDRIG_CHECK(rgb[1] == 0.0 && rgb[2] == 0.0, "fit_stack: parameters are not channel by channel");
        basis(j, k) = rgb[0];
      }
      unit[static_cast<size_t>(k)] = 0.0;
    }
  }
  const Eigen::MatrixXf fit_f = op->matrix().cast<float>(), basis_f = basis.cast<float>();
  const Eigen::VectorXd hat = (basis * op->matrix()).diagonal();
  Eigen::VectorXf loo_scale(n);  // the LOO residual is r_j / (1 - H_jj)
  for (int j = 0; j < n; ++j) loo_scale[j] = hat[j] < 1.0 - 1e-9 ? static_cast<float>(1.0 / (1.0 - hat[j])) : 1.0f;

  std::vector<int> views(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) views[static_cast<size_t>(v)] = v;
  auto opened = StackRows::open(listed.value(), views, options.linearisation, options.crop);
  if (!opened) return opened.error();
  StackRows& rows_in = opened.value();
  const int W = rows_in.width(), H = rows_in.height();

  fitting::ParameterMap map(model, W, H, W, H);
  const bool loo = model->reports_leave_one_out();
  if (loo)
    for (const char* c : {"loo.R", "loo.G", "loo.B"}) map.add_channel(c);
  // The quality channels by index (ParameterMap::set_quality looks each up by name, per texel).
  const auto channel = [&map](const std::string& name) -> cv::Mat& {
    const int i = map.image().find(name);
    VDRIG_CHECK(i >= 0, "fit_stack: no channel " + name);
    return map.image().channels[static_cast<size_t>(i)];
  };
  cv::Mat* rms_channel[3] = {&channel("rms.R"), &channel("rms.G"), &channel("rms.B")};
  cv::Mat* mpe_channel[3] = {&channel("mpe.R"), &channel("mpe.G"), &channel("mpe.B")};
  cv::Mat* loo_channel[3] = {loo ? &channel("loo.R") : nullptr, loo ? &channel("loo.G") : nullptr,
                             loo ? &channel("loo.B") : nullptr};
  cv::Mat& n_channel = channel("n");
  const int threads = options.threads > 0 ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  const int band_rows = std::clamp(kTexelsPerBand / W, 1, H), bands = (H + band_rows - 1) / band_rows;
  // Two band buffers (row j: image j's band, texel by texel): the threads decode band b + 1 into one while others
  // still fit band b from the other, so one barrier per band suffices (decoded -> fitted). Under load, every
  // barrier waits for the slowest thread to be scheduled: at 60 images of 256 x 256 the former two barriers and two
  // thread start-ups per band were most of the wall time.
  RowMajorXf buffers[2] = {RowMajorXf(n, static_cast<Eigen::Index>(band_rows) * W * 3),
                           RowMajorXf(n, static_cast<Eigen::Index>(band_rows) * W * 3)};
  // Per thread, kept from band to band (a fresh allocation per band cost page faults).
  struct Work {
    Eigen::MatrixXf coeffs;  // K x columns
    RowMajorXf residual;     // N x columns
    Eigen::Array<float, 1, Eigen::Dynamic> sq, sq_loo, pct, pct_n;
  };
  std::vector<Work> work(static_cast<size_t>(threads));
  std::vector<Status> decoded(static_cast<size_t>(n), Status::ok());
  std::barrier<> band_decoded(threads);
  parallel_for_strided(threads, threads, [&](int w) {
    for (int b = 0; b < bands; ++b) {
      const int y0 = b * band_rows, rows = std::min(band_rows, H - y0);
      RowMajorXf& values = buffers[b % 2];
      // Decoding: every thread takes its share of the photographs.
      for (int v = w; v < n; v += threads)
        decoded[static_cast<size_t>(v)] = rows_in.read_image_rows(v, rows, values.row(v).data(), 3);
      band_decoded.arrive_and_wait();
      // Every thread sees every status of the band here, so all stop at the same band.
      if (std::any_of(decoded.begin(), decoded.end(), [](const Status& s) { return !s; })) return;
      // Fitting: every thread takes its share of the band's texels, as matrix products and column reductions.
      const int texels = rows * W;
      const int first_texel = texels * w / threads, last_texel = texels * (w + 1) / threads;
      if (first_texel < last_texel) {
        Work& k = work[static_cast<size_t>(w)];
        const int cols = 3 * (last_texel - first_texel);  // column = one channel of one texel
        const auto v = values.middleCols(3 * first_texel, cols);
        k.coeffs.noalias() = fit_f * v;
        k.residual.noalias() = basis_f * k.coeffs;  // row-major like the samples: every pass below reads rows
        k.residual -= v;
        k.sq.setZero(cols);
        k.sq_loo.setZero(cols);
        k.pct.setZero(cols);
        k.pct_n.setZero(cols);
        for (int j = 0; j < n; ++j) {
          const auto r = k.residual.row(j).array();
          const auto f = v.row(j).array();
          k.sq += r.square();
          k.sq_loo += r.square() * (loo_scale[j] * loo_scale[j]);
          // Mean percentage error over the samples with a positive value (SharedDirectionLinearFit::
          // residual_quality).
          k.pct += (f > 0.0f).select(r.abs() / f, 0.0f);
          k.pct_n += (f > 0.0f).cast<float>();
        }
        std::vector<double> parameters(static_cast<size_t>(P));
        for (int i = first_texel; i < last_texel; ++i) {
          const int s = i % W, t = H - 1 - (y0 + i / W);  // texel rows grow with y, up in the image
          for (int c = 0; c < 3; ++c) {
            const Eigen::Index col = 3 * (i - first_texel) + c;
            for (int j = 0; j < K; ++j) parameters[static_cast<size_t>(c * K + j)] = k.coeffs(j, col);
            // As SharedDirectionLinearFit::residual_quality and ParameterMap::set_quality.
            rms_channel[c]->at<float>(t, s) = std::sqrt(k.sq[col] / static_cast<float>(n));
            mpe_channel[c]->at<float>(t, s) = k.pct_n[col] > 0 ? 100.0f * k.pct[col] / k.pct_n[col] : 0.0f;
            if (loo) loo_channel[c]->at<float>(t, s) = std::sqrt(k.sq_loo[col] / static_cast<float>(n));
          }
          n_channel.at<float>(t, s) = static_cast<float>(n);
          map.set_parameters(s, t, parameters);
        }
      }
      if (w == 0 && options.on_progress) options.on_progress(y0 + rows, H);  // thread 0 is the caller's
    }
  });
  for (const Status& s : decoded) VDRIG_TRY(s);
  log::get("rti")->info("fitted {} ({} images of {}x{}) from {} in one pass", model->name(), n, W, H,
                        listed->lp_file.string());
  return map;
}

}  // namespace vdrig::rti

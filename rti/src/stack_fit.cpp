#include "vdrig/rti/stack_fit.hpp"

#include <jpeglib.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cctype>
#include <csetjmp>
#include <cstdio>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <thread>
#include <vector>

#include "linear_table.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/rti/light_positions.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;
using RowMajorXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Texels fitted per band: the band's samples (images x texels x 3 floats) stay near 1.2 MB per 100 images.
constexpr int kTexelsPerBand = 1024;

/// The rows of one photograph, top to bottom, as fitted values (RGB floats), cropped.
class RowSource {
 public:
  virtual ~RowSource() = default;
  /// The next `rows` rows into out (rows x crop width x 3 floats).
  virtual Status read_rows(int rows, float* out) = 0;
};

/// Value tables of the three channels for `bits`-bit codes.
using Tables = std::array<std::vector<float>, 3>;

Tables make_tables(const Linearisation& lin, int bits) {
  Tables t;
  for (int c = 0; c < 3; ++c) t[c] = linear_table(lin, bits, lin.kind == Linearisation::Kind::kCurve ? c : 0);
  return t;
}

/// A baseline JPEG decoded a few rows at a time with libjpeg's scanline interface: a decoder holds a few rows, not
/// the image. libjpeg reports errors through error_exit, which by default ends the process: here it longjmps back
/// into the call that failed, which turns it into an error value naming the file.
class JpegRows final : public RowSource {
 public:
  static Result<std::unique_ptr<RowSource>> open(const fs::path& path, const cv::Rect& crop, const Tables* tables,
                                                 cv::Size* size) {
    auto src = std::unique_ptr<JpegRows>(new JpegRows(path, crop, tables));
    FILE* file = std::fopen(path.c_str(), "rb");
    if (!file) return make_error(ErrorCode::kIo, "opening " + path.string());
    src->file_ = file;
    if (!src->start(size)) return make_error(ErrorCode::kCorrupt, path.string() + ": " + src->message_);
    return std::unique_ptr<RowSource>(std::move(src));
  }
  ~JpegRows() override {
    if (created_) jpeg_destroy_decompress(&cinfo_);
    if (file_) std::fclose(file_);
  }

  Status read_rows(int rows, float* out) override {
    for (; skip_rows_ > 0; --skip_rows_)  // the rows above the crop, once
      if (!scanline()) return make_error(ErrorCode::kCorrupt, path_.string() + ": " + message_);
    for (int r = 0; r < rows; ++r) {
      if (!scanline()) return make_error(ErrorCode::kCorrupt, path_.string() + ": " + message_);
      const uint8_t* in = row_.data() + 3 * static_cast<size_t>(crop_.x);
      float* o = out + static_cast<size_t>(r) * crop_.width * 3;
      for (int x = 0; x < crop_.width; ++x)
        for (int c = 0; c < 3; ++c) o[3 * x + c] = (*tables_)[c][in[3 * x + c]];
    }
    return Status::ok();
  }

 private:
  struct ErrorManager {
    jpeg_error_mgr pub;
    std::jmp_buf jump;
    JpegRows* self;
  };

  JpegRows(fs::path path, const cv::Rect& crop, const Tables* tables)
      : path_(std::move(path)), crop_(crop), tables_(tables) {}

  static void on_error(j_common_ptr cinfo) {
    auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
    char text[JMSG_LENGTH_MAX];
    (*cinfo->err->format_message)(cinfo, text);
    err->self->message_ = text;
    std::longjmp(err->jump, 1);
  }
  static void on_warning(j_common_ptr /*cinfo*/, int /*level*/) {}  // corrupt-data warnings: the decoder goes on

  /// Header, colour conversion to RGB, start. False with message_ on failure.
  bool start(cv::Size* size) {
    cinfo_.err = jpeg_std_error(&err_.pub);
    err_.pub.error_exit = on_error;
    err_.pub.emit_message = on_warning;
    err_.self = this;
    if (setjmp(err_.jump)) return false;
    jpeg_create_decompress(&cinfo_);
    created_ = true;
    jpeg_stdio_src(&cinfo_, file_);
    jpeg_read_header(&cinfo_, TRUE);
    if (cinfo_.progressive_mode) {
      message_ = "progressive JPEG";  // the caller decodes it whole instead (a progressive decoder buffers it all)
      return false;
    }
    cinfo_.out_color_space = JCS_RGB;
    jpeg_start_decompress(&cinfo_);
    *size = cv::Size(static_cast<int>(cinfo_.output_width), static_cast<int>(cinfo_.output_height));
    if (crop_.width == 0) crop_ = cv::Rect(0, 0, size->width, size->height);
    row_.resize(static_cast<size_t>(cinfo_.output_width) * 3);
    skip_rows_ = crop_.y;
    return true;
  }

  bool scanline() {
    if (setjmp(err_.jump)) return false;
    JSAMPROW rows[1] = {row_.data()};
    if (jpeg_read_scanlines(&cinfo_, rows, 1) != 1) {
      message_ = "fewer rows than the header says";
      return false;
    }
    return true;
  }

  fs::path path_;
  cv::Rect crop_;
  const Tables* tables_;
  FILE* file_ = nullptr;
  jpeg_decompress_struct cinfo_{};
  ErrorManager err_{};
  bool created_ = false;
  std::vector<uint8_t> row_;
  int skip_rows_ = 0;
  std::string message_;
};

/// Any other image (PNG, TIFF, EXR, progressive JPEG), decoded whole and kept at its own depth (8 or 16 bits, or
/// float for EXR): a stack of those is held in memory, one byte per sample for 8-bit images.
class DecodedRows final : public RowSource {
 public:
  static Result<std::unique_ptr<RowSource>> open(const fs::path& path, const cv::Rect& crop, const Linearisation& lin,
                                                 cv::Size* size) {
    auto src = std::unique_ptr<DecodedRows>(new DecodedRows());
    std::string ext = path.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".exr") {
      auto image = read_linear_image(path, lin, std::nullopt);  // floats pass unchanged
      if (!image) return image.error();
      src->image_ = image.value();
    } else {
      auto decoded = read_png(path);  // PNG or JPEG, depth kept
      if (!decoded) return decoded.error();
      cv::Mat& image = decoded.value();
      const int code = image.channels() == 1   ? cv::COLOR_GRAY2RGB
                       : image.channels() == 4 ? cv::COLOR_BGRA2RGB
                       : image.channels() == 3 ? cv::COLOR_BGR2RGB
                                               : -1;
      if (code < 0)
        return make_error(ErrorCode::kCorrupt, path.string() + ": " + std::to_string(image.channels()) + " channels");
      cv::cvtColor(image, src->image_, code);
      if (src->image_.depth() != CV_8U && src->image_.depth() != CV_16U)
        return make_error(ErrorCode::kUnsupported, path.string() + ": only 8-, 16-bit and float images are read");
      const int bits = src->image_.depth() == CV_8U ? 8 : 16;
      if (lin.kind == Linearisation::Kind::kCurve && lin.curve.bits() != bits)
        return make_error(ErrorCode::kInvalidArgument, path.string() + ": a " + std::to_string(bits) +
                                                           "-bit image and a " + std::to_string(lin.curve.bits()) +
                                                           "-bit response");
      src->tables_ = make_tables(lin, bits);
    }
    *size = src->image_.size();
    src->crop_ = crop.width == 0 ? cv::Rect(0, 0, size->width, size->height) : crop;
    src->next_row_ = src->crop_.y;
    return std::unique_ptr<RowSource>(std::move(src));
  }

  Status read_rows(int rows, float* out) override {
    for (int r = 0; r < rows; ++r, ++next_row_) {
      float* o = out + static_cast<size_t>(r) * crop_.width * 3;
      for (int x = 0; x < crop_.width; ++x)
        for (int c = 0; c < 3; ++c) {
          const int i = 3 * (crop_.x + x) + c;
          switch (image_.depth()) {
            case CV_8U:
              o[3 * x + c] = tables_[c][image_.ptr<uint8_t>(next_row_)[i]];
              break;
            case CV_16U:
              o[3 * x + c] = tables_[c][image_.ptr<uint16_t>(next_row_)[i]];
              break;
            default:
              o[3 * x + c] = image_.ptr<float>(next_row_)[i];
          }
        }
    }
    return Status::ok();
  }

 private:
  cv::Mat image_;
  Tables tables_;
  cv::Rect crop_;
  int next_row_ = 0;
};

bool is_jpeg(const fs::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".jpg" || ext == ".jpeg";
}

/// Runs body(i) for i in [0, n) on `threads` threads (the calling one included), each taking every threads-th i.
template <typename Body>
void parallel_for(int n, int threads, const Body& body) {
  std::vector<std::thread> pool;
  for (int w = 1; w < threads; ++w)
    pool.emplace_back([&, w] {
      for (int i = w; i < n; i += threads) body(i);
    });
  for (int i = 0; i < n; i += threads) body(i);
  for (auto& t : pool) t.join();
}

}  // namespace

Result<fitting::ParameterMap> fit_stack(const fs::path& stack, const StackFitOptions& options) {
  const fitting::ModelPtr& model = options.model;
  VDRIG_CHECK(model != nullptr, "fit_stack: no model");
  if (!model->linear_in_shared_directions())
    return make_error(ErrorCode::kInvalidArgument,
                      model->name() +
                          " is not one linear fit per direction set: import the stack (vdrig rti import) "
                          "and fit the observation map (vdrig rti fit STACK.vdobs)");
  auto lp = find_light_positions(stack);
  if (!lp) return lp.error();
  auto lights = read_light_positions(lp.value());
  if (!lights) return lights.error();
  const int n = static_cast<int>(lights->size());
  for (int v = 0; v < n; ++v) {
    std::error_code ec;
    if (!fs::is_regular_file((*lights)[static_cast<size_t>(v)].image, ec))
      return make_error(ErrorCode::kNotFound, "image " + std::to_string(v + 1) + " of " + lp->string() + " (" +
                                                  (*lights)[static_cast<size_t>(v)].image.string() +
                                                  ") does not exist");
  }

  // The model's operator P (K x N per channel) on the stack's directions, and its basis Y (N x K) from evaluate()
  // of unit parameters: the fit is c = P f, its prediction Y c, its hat matrix H = Y P.
  std::vector<Vec3d> dirs;
  for (const LightPosition& l : lights.value()) dirs.push_back(l.direction);
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

  // Open every photograph; the first fixes the size, the crop must lie inside it.
  Tables tables8 = make_tables(options.linearisation, 8);
  std::vector<std::unique_ptr<RowSource>> sources(static_cast<size_t>(n));
  cv::Rect crop = options.crop.value_or(cv::Rect());
  cv::Size first;
  for (int v = 0; v < n; ++v) {
    const fs::path& path = (*lights)[static_cast<size_t>(v)].image;
    cv::Size size;
    Result<std::unique_ptr<RowSource>> src = make_error(ErrorCode::kInternal, "");
    if (v > 0 && crop.width == 0) crop = cv::Rect(0, 0, first.width, first.height);
    if (is_jpeg(path) && options.linearisation.kind == Linearisation::Kind::kCurve &&
        options.linearisation.curve.bits() != 8)
      return make_error(ErrorCode::kInvalidArgument, path.string() + ": an 8-bit image and a " +
                                                         std::to_string(options.linearisation.curve.bits()) +
                                                         "-bit response");
    if (is_jpeg(path)) src = JpegRows::open(path, crop, &tables8, &size);
    if (!is_jpeg(path) || (!src && src.error().message.ends_with("progressive JPEG")))
      src = DecodedRows::open(path, crop, options.linearisation, &size);
    if (!src) return src.error();
    if (v == 0) {
      first = size;
      if (options.crop && (crop.x < 0 || crop.y < 0 || crop.width <= 0 || crop.height <= 0 ||
                           crop.x + crop.width > size.width || crop.y + crop.height > size.height))
        return make_error(ErrorCode::kInvalidArgument,
                          "crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," +
                              std::to_string(crop.width) + "," + std::to_string(crop.height) + " is not inside the " +
                              std::to_string(size.width) + "x" + std::to_string(size.height) + " images");
    } else if (size != first) {
      return make_error(ErrorCode::kInvalidArgument,
                        "image " + std::to_string(v + 1) + " (" + path.string() + ") is " + std::to_string(size.width) +
                            "x" + std::to_string(size.height) + ", the first is " + std::to_string(first.width) + "x" +
                            std::to_string(first.height));
    }
    sources[static_cast<size_t>(v)] = std::move(src.value());
  }
  if (crop.width == 0) crop = cv::Rect(0, 0, first.width, first.height);
  const int W = crop.width, H = crop.height;

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
  const int band_rows = std::clamp(kTexelsPerBand / W, 1, H);
  RowMajorXf values(n, static_cast<Eigen::Index>(band_rows) * W * 3);  // row j: image j's band, texel by texel
  // Per thread, kept from band to band (a fresh allocation per band cost page faults).
  struct Work {
    Eigen::MatrixXf coeffs;  // K x columns
    RowMajorXf residual;     // N x columns
    Eigen::Array<float, 1, Eigen::Dynamic> sq, sq_loo, pct, pct_n;
  };
  std::vector<Work> work(static_cast<size_t>(threads));
  for (int y0 = 0; y0 < H; y0 += band_rows) {
    const int rows = std::min(band_rows, H - y0);
    // Decoding: every thread takes its share of the photographs.
    std::vector<Status> failed(static_cast<size_t>(n), Status::ok());
    parallel_for(n, threads, [&](int v) {
      failed[static_cast<size_t>(v)] = sources[static_cast<size_t>(v)]->read_rows(rows, values.row(v).data());
    });
    for (const Status& s : failed) VDRIG_TRY(s);
    // Fitting: every thread takes its share of the band's texels, as matrix products and column reductions.
    const int texels = rows * W;
    parallel_for(threads, threads, [&](int w) {
      const int first_texel = texels * w / threads, last_texel = texels * (w + 1) / threads;
      if (first_texel == last_texel) return;
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
        // Mean percentage error over the samples with a positive value (SharedDirectionLinearFit::residual_quality).
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
    });
    if (options.on_progress) options.on_progress(y0 + rows, H);
  }
  log::get("rti")->info("fitted {} ({} images of {}x{}) from {} in one pass", model->name(), n, W, H, lp->string());
  return map;
}

}  // namespace vdrig::rti

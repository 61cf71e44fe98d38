#include "stack_reader.hpp"

#include <jpeglib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <csetjmp>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>

#include "linear_table.hpp"
#include "vdrig/core/image_io.hpp"

namespace vdrig::rti {

namespace fs = std::filesystem;

/// The rows of one photograph, top to bottom, as fitted values (RGB floats), cropped.
class RowSource {
 public:
  virtual ~RowSource() = default;
  /// The next `rows` rows: channel c of texel x (counted over the rows, row by row) into out[x * texel_stride + c].
  virtual Status read_rows(int rows, float* out, std::ptrdiff_t texel_stride) = 0;
};

namespace {

using Tables = ValueTables;

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

  Status read_rows(int rows, float* out, std::ptrdiff_t texel_stride) override {
    for (; skip_rows_ > 0; --skip_rows_)  // the rows above the crop, once
      if (!scanline()) return make_error(ErrorCode::kCorrupt, path_.string() + ": " + message_);
    for (int r = 0; r < rows; ++r) {
      if (!scanline()) return make_error(ErrorCode::kCorrupt, path_.string() + ": " + message_);
      const uint8_t* in = row_.data() + 3 * static_cast<size_t>(crop_.x);
      float* o = out + static_cast<std::ptrdiff_t>(r) * crop_.width * texel_stride;
      for (int x = 0; x < crop_.width; ++x, o += texel_stride)
        for (int c = 0; c < 3; ++c) o[c] = (*tables_)[c][in[3 * x + c]];
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

  Status read_rows(int rows, float* out, std::ptrdiff_t texel_stride) override {
    for (int r = 0; r < rows; ++r, ++next_row_) {
      float* row = out + static_cast<std::ptrdiff_t>(r) * crop_.width * texel_stride;
      for (int x = 0; x < crop_.width; ++x)
        for (int c = 0; c < 3; ++c) {
          float& o = row[x * texel_stride + c];
          const int i = 3 * (crop_.x + x) + c;
          switch (image_.depth()) {
            case CV_8U:
              o = tables_[c][image_.ptr<uint8_t>(next_row_)[i]];
              break;
            case CV_16U:
              o = tables_[c][image_.ptr<uint16_t>(next_row_)[i]];
              break;
            default:
              o = image_.ptr<float>(next_row_)[i];
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

}  // namespace

Result<StackList> list_stack(const fs::path& stack) {
  auto lp = find_light_positions(stack);
  if (!lp) return lp.error();
  auto lights = read_light_positions(lp.value());
  if (!lights) return lights.error();
  for (size_t v = 0; v < lights->size(); ++v) {
    std::error_code ec;
    if (!fs::is_regular_file((*lights)[v].image, ec))
      return make_error(ErrorCode::kNotFound, "image " + std::to_string(v + 1) + " of " + lp->string() + " (" +
                                                  (*lights)[v].image.string() + ") does not exist");
  }
  return StackList{lp.value(), std::move(lights.value())};
}

StackRows::StackRows() = default;
StackRows::StackRows(StackRows&&) noexcept = default;
StackRows& StackRows::operator=(StackRows&&) noexcept = default;
StackRows::~StackRows() = default;

Result<StackRows> StackRows::open(const StackList& list, const std::vector<int>& views, const Linearisation& lin,
                                  const std::optional<cv::Rect>& requested_crop) {
  // The first image fixes the size, the crop must lie inside it.
  StackRows out;
  out.tables8_ = std::make_unique<Tables>(make_tables(lin, 8));
  cv::Rect crop = requested_crop.value_or(cv::Rect());
  cv::Size first;
  for (size_t i = 0; i < views.size(); ++i) {
    const fs::path& path = list.lights[static_cast<size_t>(views[i])].image;
    const int number = views[i] + 1;
    cv::Size size;
    Result<std::unique_ptr<RowSource>> src = make_error(ErrorCode::kInternal, "");
    if (i > 0 && crop.width == 0) crop = cv::Rect(0, 0, first.width, first.height);
    if (is_jpeg(path) && lin.kind == Linearisation::Kind::kCurve && lin.curve.bits() != 8)
      return make_error(ErrorCode::kInvalidArgument,
                        path.string() + ": an 8-bit image and a " + std::to_string(lin.curve.bits()) + "-bit response");
    if (is_jpeg(path)) src = JpegRows::open(path, crop, out.tables8_.get(), &size);
    if (!is_jpeg(path) || (!src && src.error().message.ends_with("progressive JPEG")))
      src = DecodedRows::open(path, crop, lin, &size);
    if (!src) return src.error();
    if (i == 0) {
      first = size;
      if (requested_crop && (crop.x < 0 || crop.y < 0 || crop.width <= 0 || crop.height <= 0 ||
                             crop.x + crop.width > size.width || crop.y + crop.height > size.height))
        return make_error(ErrorCode::kInvalidArgument,
                          "crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," +
                              std::to_string(crop.width) + "," + std::to_string(crop.height) + " is not inside the " +
                              std::to_string(size.width) + "x" + std::to_string(size.height) + " images");
    } else if (size != first) {
      return make_error(ErrorCode::kInvalidArgument,
                        "image " + std::to_string(number) + " (" + path.string() + ") is " +
                            std::to_string(size.width) + "x" + std::to_string(size.height) + ", the first is " +
                            std::to_string(first.width) + "x" + std::to_string(first.height));
    }
    out.sources_.push_back(std::move(src.value()));
  }
  out.crop_ = crop.width == 0 ? cv::Rect(0, 0, first.width, first.height) : crop;
  return out;
}

Status StackRows::read_rows(int rows, float* out, std::ptrdiff_t image_stride, std::ptrdiff_t texel_stride,
                            int threads) {
  const int n = images();
  std::vector<Status> failed(static_cast<size_t>(n), Status::ok());
  parallel_for_strided(n, threads, [&](int v) {
    failed[static_cast<size_t>(v)] =
        sources_[static_cast<size_t>(v)]->read_rows(rows, out + v * image_stride, texel_stride);
  });
  for (const Status& s : failed) VDRIG_TRY(s);
  return Status::ok();
}

Status StackRows::read_image_rows(int j, int rows, float* out, std::ptrdiff_t texel_stride) {
  return sources_[static_cast<size_t>(j)]->read_rows(rows, out, texel_stride);
}

}  // namespace vdrig::rti

#include "vdrig/rti/import.hpp"

#include <array>
#include <cmath>
#include <future>
#include <opencv2/imgproc.hpp>

#include "linear_table.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;

double srgb_to_linear(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }

Result<cv::Mat> read_exr_rgb(const fs::path& path) {
  auto exr = read_exr(path);
  if (!exr) return exr.error();
  auto plane = [&](const char* a, const char* b) {
    int i = exr->find(a);
    if (i < 0) i = exr->find(b);
    return i < 0 ? cv::Mat() : exr->channels[static_cast<size_t>(i)];
  };
  cv::Mat r = plane("R", "Y"), g = plane("G", "Y"), b = plane("B", "Y");
  if (r.empty() || g.empty() || b.empty())
    return make_error(ErrorCode::kCorrupt, path.string() + ": an EXR without R, G, B (or Y) channels");
  cv::Mat rgb;
  cv::merge(std::vector<cv::Mat>{r, g, b}, rgb);
  return rgb;
}

/// kInvalidArgument unless `crop` is a non-empty rectangle inside an image of `size`; `what` names the images.
Status check_crop(const cv::Rect& crop, const cv::Size& size, const std::string& what) {
  if ((crop & cv::Rect(0, 0, size.width, size.height)) == crop && !crop.empty()) return Status::ok();
  return make_error(ErrorCode::kInvalidArgument, "crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," +
                                                     std::to_string(crop.width) + "," + std::to_string(crop.height) +
                                                     " is not inside the " + std::to_string(size.width) + "x" +
                                                     std::to_string(size.height) + " " + what);
}

}  // namespace

std::vector<float> linear_table(const Linearisation& lin, int bits, int channel) {
  const int max_code = (1 << bits) - 1;
  std::vector<float> table(static_cast<size_t>(max_code) + 1);
  for (int code = 0; code <= max_code; ++code) {
    const double v = static_cast<double>(code) / max_code;
    switch (lin.kind) {
      case Linearisation::Kind::kSrgb:
        table[code] = static_cast<float>(srgb_to_linear(v));
        break;
      case Linearisation::Kind::kCodes:
        table[code] = static_cast<float>(v);
        break;
      case Linearisation::Kind::kCurve:
        table[code] = static_cast<float>(lin.curve.inverse(channel, code));
        break;
    }
  }
  return table;
}

Result<Linearisation> Linearisation::parse(const std::string& text) {
  Linearisation lin;
  if (text == "sRGB" || text == "srgb") {
    lin.kind = Kind::kSrgb;
    return lin;
  }
  if (text == "codes" || text == "linear") return lin;
  auto json = read_json_file(text);
  if (!json)
    return make_error(json.error().code,
                      "response \"" + text + "\" (codes, sRGB or a response JSON file): " + json.error().message);
  auto curve = ResponseCurve::from_json(json.value());
  if (!curve) return make_error(ErrorCode::kInvalidArgument, text + ": " + curve.error().message);
  lin.kind = Kind::kCurve;
  lin.curve = std::move(curve.value());
  return lin;
}

Result<cv::Mat> read_linear_image(const fs::path& path, const Linearisation& linearisation,
                                  const std::optional<cv::Rect>& crop) {
  cv::Mat image;
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".exr") {
    auto rgb = read_exr_rgb(path);
    if (!rgb) return rgb.error();
    image = rgb.value();
  } else {
    auto decoded = read_png(path);  // PNG or JPEG, depth kept, size-checked
    if (!decoded) return decoded.error();
    image = decoded.value();
    if (image.channels() == 1)
      cv::cvtColor(image, image, cv::COLOR_GRAY2RGB);
    else if (image.channels() == 4)
      cv::cvtColor(image, image, cv::COLOR_BGRA2RGB);
    else if (image.channels() == 3)
      cv::cvtColor(image, image, cv::COLOR_BGR2RGB);
    else
      return make_error(ErrorCode::kCorrupt, path.string() + ": " + std::to_string(image.channels()) + " channels");
  }
  if (crop) {
    VDRIG_TRY(check_crop(*crop, image.size(), "image " + path.string()));
    image = image(*crop);
  }
  const int depth = image.depth();
  if (depth == CV_32F) return image.clone();
  if (depth != CV_8U && depth != CV_16U)
    return make_error(ErrorCode::kUnsupported, path.string() + ": only 8-, 16-bit and float images are read");
  const int bits = depth == CV_8U ? 8 : 16;
  if (linearisation.kind == Linearisation::Kind::kCurve && linearisation.curve.bits() != bits)
    return make_error(ErrorCode::kInvalidArgument, path.string() + ": a " + std::to_string(bits) + "-bit image and a " +
                                                       std::to_string(linearisation.curve.bits()) + "-bit response");
  std::array<std::vector<float>, 3> tables;
  for (int c = 0; c < 3; ++c)
    tables[c] = linear_table(linearisation, bits, linearisation.kind == Linearisation::Kind::kCurve ? c : 0);
  cv::Mat out(image.size(), CV_32FC3);
  for (int y = 0; y < image.rows; ++y) {
    float* o = out.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x)
      for (int c = 0; c < 3; ++c)
        o[3 * x + c] =
            bits == 8 ? tables[c][image.ptr<uint8_t>(y)[3 * x + c]] : tables[c][image.ptr<uint16_t>(y)[3 * x + c]];
  }
  return out;
}

Result<ImportSummary> import_stack(const fs::path& stack, const fs::path& out, const ImportOptions& options) {
  auto lp = find_light_positions(stack);
  if (!lp) return lp.error();
  auto lights = read_light_positions(lp.value());
  if (!lights) return lights.error();
  const int n = static_cast<int>(lights->size());
  for (int v = 0; v < n; ++v) {
    const fs::path& image = (*lights)[v].image;
    std::error_code ec;
    if (!fs::is_regular_file(image, ec))
      return make_error(ErrorCode::kNotFound, "image " + std::to_string(v + 1) + " of " + lp->string() + " (" +
                                                  image.string() + ") does not exist");
  }
  ImportSummary summary{lp.value(), n, 0, 0};
  std::optional<fitting::ObsMapWriter> writer;
  cv::Size first_size;
  // Decoding (the larger part of an image's time) of image v + 1 overlaps the spill of image v.
  auto decode = [&](int v) {
    return std::async(std::launch::async, [&lights, &options, v] {
      return read_linear_image((*lights)[static_cast<size_t>(v)].image, options.linearisation, std::nullopt);
    });
  };
  std::future<Result<cv::Mat>> next = decode(0);
  for (int v = 0; v < n; ++v) {
    const LightPosition& light = (*lights)[static_cast<size_t>(v)];
    // Size check on the uncropped image: the crop is in the frame every image must share.
    auto image = next.get();
    if (v + 1 < n) next = decode(v + 1);
    if (!image) return image.error();
    if (v == 0) first_size = image->size();
    if (image->size() != first_size)
      return make_error(ErrorCode::kInvalidArgument,
                        "image " + std::to_string(v + 1) + " (" + light.image.string() + ") is " +
                            std::to_string(image->cols) + "x" + std::to_string(image->rows) + ", the first is " +
                            std::to_string(first_size.width) + "x" + std::to_string(first_size.height));
    cv::Mat rgb = image.value();
    if (options.crop) {
      VDRIG_TRY(check_crop(*options.crop, rgb.size(), "images"));
      rgb = rgb(*options.crop);
    }
    cv::flip(rgb, rgb, 0);  // texel rows grow with y (up in the image)
    if (!writer) {
      summary.width = rgb.cols;
      summary.height = rgb.rows;
      fitting::ObservationMapSpec spec{rgb.cols, rgb.rows, static_cast<double>(rgb.cols),
                                       static_cast<double>(rgb.rows)};
      auto w = fitting::ObsMapWriter::create(out, spec, n, options.file);
      if (!w) return w.error();
      writer.emplace(std::move(w.value()));
    }
    VDRIG_TRY(writer->add_shared_direction_view(v, rgb, light.direction.cast<float>()));
    if (options.on_image) options.on_image(v + 1, n);
  }
  VDRIG_TRY(writer->finish());
  log::get("rti")->info("imported {} images of {}x{} from {} into {}", n, summary.width, summary.height, lp->string(),
                        out.string());
  return summary;
}

}  // namespace vdrig::rti

// `vdrig rti import|fit|export`: Reflectance Transformation Imaging stacks (photographs + .lp light list) through
// vdrig's fitting and out to the files RTIViewer and OpenLIME read (rti/, docs/rti.md).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>
#include <vector>

#include "cmd_rti_rbf.hpp"
#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/rti/export.hpp"
#include "vdrig/rti/fitted_files.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/rti/stack_fit.hpp"

namespace vdrig::app {
namespace {
namespace fs = std::filesystem;

Error usage(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }

Result<cv::Rect> parse_crop(const std::string& text) {
  std::istringstream in(text);
  int v[4];
  char comma;
  if (!(in >> v[0] >> comma >> v[1] >> comma >> v[2] >> comma >> v[3]) || !in.eof() || v[0] < 0 || v[1] < 0 ||
      v[2] <= 0 || v[3] <= 0)
    return usage("--crop must be x,y,w,h (pixels, w and h > 0), got \"" + text + "\"");
  return cv::Rect(v[0], v[1], v[2], v[3]);
}

struct ImportArgs {
  std::string stack, out, crop, response = "codes", compression = "zstd", model = "hsh:3";
  int tile = 16;
  int zstd_level = -5;  // zstd's fast levels: less CPU for a slightly larger file (docs/rti.md)
};

/// A fitted file (.ptm, .rti, relight folder) made elsewhere -> a parameter map that view, render, compare and
/// rti export take.
Status run_import_fitted(const ImportArgs& a) {
  if (!a.crop.empty()) return usage("--crop applies to stacks of photographs, not to a fitted file");
  if (fs::path(a.out).extension() != ".exr")
    return usage("--out: a fitted file is imported as a parameter map (.exr), got \"" + a.out + "\"");
  auto map = rti::read_fitted_file(a.stack, a.model);
  if (!map) return map.error();
  VDRIG_TRY(map->write(a.out));
  std::printf("wrote %s (%s, %dx%d texels) from %s\n", a.out.c_str(), map->model().name().c_str(), map->texels_s(),
              map->texels_t(), a.stack.c_str());
  return Status::ok();
}

Status run_import(const ImportArgs& a) {
  if (rti::is_fitted_file(a.stack)) return run_import_fitted(a);
  rti::ImportOptions options;
  if (!a.crop.empty()) {
    auto crop = parse_crop(a.crop);
    if (!crop) return crop.error();
    options.crop = crop.value();
  }
  auto lin = rti::Linearisation::parse(a.response);
  if (!lin) return lin.error();
  options.linearisation = std::move(lin.value());
  // zstd: an RTI map repeats each view's direction in every texel, which compresses ~20x and saves writing and
  // reading hundreds of MB for a little CPU (docs/rti.md).
  options.file.compression = a.compression == "zstd" ? fitting::ObsCompression::kZstd : fitting::ObsCompression::kNone;
  options.file.zstd_level = a.zstd_level;
  options.file.tile_size = a.tile;
  std::string why;
  if (!options.file.is_valid(&why)) return usage(why);
  ProgressLine progress;
  options.on_image = [&progress](int done, int total) { progress.update(done, total, "  images %d/%d", done, total); };
  auto summary = rti::import_stack(a.stack, a.out, options);
  progress.finish();
  if (!summary) return summary.error();
  std::printf("wrote %s: %d images of %dx%d from %s\n", a.out.c_str(), summary->images, summary->width, summary->height,
              summary->lp_file.c_str());
  return Status::ok();
}

struct FitArgs {
  std::string input, model = "hsh:3", out, response = "codes", crop;
  int threads = 0, quality = 95;
};

/// Median over texels of the mean of three channels, in 8-bit codes (x 255).
float median_codes(const fitting::ParameterMap& map, const std::string& prefix) {
  // The channels looked up once (by name per texel, this took 10% of a small stack's fit).
  const auto& channels = map.image().channels;
  const cv::Mat& r = channels[static_cast<size_t>(map.image().find(prefix + "R"))];
  const cv::Mat& g = channels[static_cast<size_t>(map.image().find(prefix + "G"))];
  const cv::Mat& b = channels[static_cast<size_t>(map.image().find(prefix + "B"))];
  std::vector<float> v;
  v.reserve(static_cast<size_t>(map.texels_s()) * static_cast<size_t>(map.texels_t()));
  for (int t = 0; t < map.texels_t(); ++t)
    for (int s = 0; s < map.texels_s(); ++s)
      v.push_back(255.0f * (r.at<float>(t, s) + g.at<float>(t, s) + b.at<float>(t, s)) / 3.0f);
  if (v.empty()) return 0.0f;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// A stack of photographs (an .lp, or a folder holding one) rather than an observation-map file.
bool is_stack(const std::string& input) {
  std::error_code ec;
  return fs::is_directory(input, ec) || fs::path(input).extension() == ".lp";
}

/// What --out asks for: a parameter map (.exr), a .ptm or .rti file, or else a relight folder.
std::optional<rti::ExportFormat> out_format(const std::string& out) {
  const std::string ext = fs::path(out).extension().string();
  if (ext == ".exr") return std::nullopt;
  if (ext == ".ptm") return rti::ExportFormat::kPtm;
  if (ext == ".rti") return rti::ExportFormat::kRti;
  return rti::ExportFormat::kRelight;
}

Status run_fit(const FitArgs& a) {
  auto model = fitting::parse_model(a.model);
  if (!model) return model.error();
  const std::optional<rti::ExportFormat> format = out_format(a.out);
  if (format) {  // refuse a model the format cannot hold before fitting, not after
    const fitting::ModelBasis basis = model.value()->coefficient_basis();
    using Kind = fitting::ModelBasis::Kind;
    const bool fits = *format == rti::ExportFormat::kPtm
                          ? basis.kind == Kind::kPtmRgb || basis.kind == Kind::kPtmLrgb
                          : (basis.kind == Kind::kHsh && (basis.bands == 2 || basis.bands == 3)) ||
                                (*format == rti::ExportFormat::kRelight && basis.kind == Kind::kPtmRgb);
    if (!fits)
      return usage("--out " + a.out + ": " + model.value()->name() +
                   " cannot be written there (.ptm: ptm:rgb|lrgb; .rti: hsh:2|3; a relight folder: ptm:rgb, hsh:2|3; "
                   ".exr: any)");
  }
  ProgressLine progress;
  Result<fitting::ParameterMap> map = make_error(ErrorCode::kInternal, "not fitted");
  if (is_stack(a.input)) {
    // Straight from the photographs, one pass (rti/stack_fit.hpp): no observation map on disk.
    rti::StackFitOptions options;
    options.model = model.value();
    options.threads = a.threads;
    auto lin = rti::Linearisation::parse(a.response);
    if (!lin) return lin.error();
    options.linearisation = std::move(lin.value());
    if (!a.crop.empty()) {
      auto crop = parse_crop(a.crop);
      if (!crop) return crop.error();
      options.crop = crop.value();
    }
    options.on_progress = [&progress](int done, int total) {
      progress.update(done, total, "  rows %d/%d", done, total);
    };
    map = rti::fit_stack(a.input, options);
  } else {
    if (!a.crop.empty() || a.response != "codes")
      return usage("--crop and --response apply to a stack of photographs; " + a.input +
                   " was imported with its own (vdrig rti import)");
    auto obs = fitting::ObsMapReader::open(a.input);
    if (!obs) return obs.error();
    fitting::MapFitOptions options;
    options.model = model.value();
    options.threads = a.threads;
    options.on_progress = [&progress](const fitting::MapFitProgress& p) {
      progress.update(p.texels_done, p.texels_total, "  texels %d/%d", p.texels_done, p.texels_total);
    };
    map = fitting::fit_parameter_map(obs.value(), options);
  }
  progress.finish();
  if (!map) return map.error();
  if (format) {
    rti::ExportOptions options;
    options.jpeg_quality = a.quality;
    VDRIG_TRY(rti::export_map(map.value(), *format, a.out, options));
  } else {
    VDRIG_TRY(map->write(a.out));
  }
  std::printf("wrote %s (%s, %dx%d texels); median RMS %.3f codes", a.out.c_str(), map->model().name().c_str(),
              map->texels_s(), map->texels_t(), median_codes(map.value(), "rms."));
  if (map->has("loo.R")) std::printf(", median leave-one-out RMS %.3f codes", median_codes(map.value(), "loo."));
  std::printf("\n");
  return Status::ok();
}

struct ExportArgs {
  std::string map, format, out;
  int quality = 95;
};

Status run_export(const ExportArgs& a) {
  auto format = rti::parse_export_format(a.format);
  if (!format) return format.error();
  auto map = fitting::ParameterMap::read(a.map);
  if (!map) return map.error();
  rti::ExportOptions options;
  options.jpeg_quality = a.quality;
  VDRIG_TRY(rti::export_map(map.value(), format.value(), a.out, options));
  std::printf("wrote %s\n", a.out.c_str());
  return Status::ok();
}

const CommandRegistrar kRti([](CLI::App& root) {
  auto* rti = root.add_subcommand("rti", "RTI stacks: import photographs + .lp, fit, export .ptm/.rti/relight");
  rti->require_subcommand(1);
  {
    auto a = std::make_shared<ImportArgs>();
    auto* cmd = rti->add_subcommand("import",
                                    "photographs + .lp light list -> observation-map file; or a fitted .ptm, .rti, "
                                    "relight folder -> parameter map");
    cmd->add_option("stack", a->stack,
                    "the .lp file, or a folder holding exactly one; or a fitted .ptm, .rti, relight folder")
        ->required();
    cmd->add_option("--out", a->out, "observation-map file to write (.vdobs), or a parameter map (.exr)")->required();
    cmd->add_option("--crop", a->crop, "x,y,w,h in image pixels from the top-left corner");
    cmd->add_option("--response", a->response,
                    "what is fitted: codes (as RTI viewers show them) | sRGB (linear radiance) | a response JSON")
        ->capture_default_str();
    cmd->add_option("--compression", a->compression, "observation map: none | zstd")
        ->check(CLI::IsMember({"none", "zstd"}))
        ->capture_default_str();
    cmd->add_option("--tile", a->tile, "observation map: texels per tile side")->capture_default_str();
    cmd->add_option("--zstd-level", a->zstd_level, "observation map: zstd level (negative: zstd's fast levels)")
        ->capture_default_str();
    cmd->add_option("--model", a->model,
                    "relight rbf folders: the model fitted to the basis (vdrig has no rbf model): hsh:N, ptm:rgb")
        ->capture_default_str();
    cmd->callback([a] { finish(run_import(*a)); });
  }
  {
    auto a = std::make_shared<FitArgs>();
    auto* cmd = rti->add_subcommand("fit",
                                    "fit a stack (photographs + .lp, in one pass) or an imported observation map -> "
                                    "parameter map with RMS and leave-one-out, or straight to .ptm/.rti/relight");
    cmd->add_option("input", a->input,
                    "the stack (its .lp, or a folder holding one), or an observation-map file (vdrig rti import)")
        ->required();
    cmd->add_option("--model", a->model, fitting::model_registry().syntax())->capture_default_str();
    cmd->add_option("--out", a->out,
                    "a parameter map (.exr), a .ptm or .rti file, or a folder (the relight format OpenLIME reads)")
        ->required();
    cmd->add_option("--response", a->response,
                    "stacks: what is fitted: codes (as RTI viewers show them) | sRGB (linear radiance) | a response "
                    "JSON")
        ->capture_default_str();
    cmd->add_option("--crop", a->crop, "stacks: x,y,w,h in image pixels from the top-left corner");
    cmd->add_option("--quality", a->quality, "relight: JPEG quality 1..100")->capture_default_str();
    cmd->add_option("--threads", a->threads, "worker threads (0: all cores)")->capture_default_str();
    cmd->callback([a] { finish(run_fit(*a)); });
  }
  {
    auto a = std::make_shared<ExportArgs>();
    auto* cmd = rti->add_subcommand("export", "parameter map -> .ptm (ptm:rgb|lrgb), .rti (hsh:2|3), relight folder");
    cmd->add_option("map", a->map, "parameter map (.exr)")->required();
    cmd->add_option("--format", a->format, "ptm | rti | relight")->required();
    cmd->add_option("--out", a->out, "file (ptm, rti) or folder (relight) to write")->required();
    cmd->add_option("--quality", a->quality, "relight: JPEG quality 1..100")->capture_default_str();
    cmd->callback([a] { finish(run_export(*a)); });
  }
  add_rti_rbf_command(*rti);  // `vdrig rti rbf` (cmd_rti_rbf.cpp)
});

}  // namespace
}  // namespace vdrig::app

// `vdrig rti import|fit|export`: Reflectance Transformation Imaging stacks (photographs + .lp light list) through
// vdrig's fitting and out to the files RTIViewer and OpenLIME read (rti/, docs/rti.md).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <vector>

#include "cmd_rti_rbf.hpp"
#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/rti/export.hpp"
#include "vdrig/rti/import.hpp"

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
  std::string stack, out, crop, response = "sRGB", compression = "zstd";
  int tile = 16;
  int zstd_level = -5;  // zstd's fast levels: less CPU for a slightly larger file (docs/rti.md)
};

Status run_import(const ImportArgs& a) {
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
  std::string obsmap, model = "hsh:3", out;
  int threads = 0;
};

/// Median over texels of the mean of three channels, in 8-bit codes (x 255).
float median_codes(const fitting::ParameterMap& map, const std::string& prefix) {
  std::vector<float> v;
  for (int t = 0; t < map.texels_t(); ++t)
    for (int s = 0; s < map.texels_s(); ++s)
      v.push_back(255.0f * (map.at(prefix + "R", s, t) + map.at(prefix + "G", s, t) + map.at(prefix + "B", s, t)) /
                  3.0f);
  if (v.empty()) return 0.0f;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

Status run_fit(const FitArgs& a) {
  auto model = fitting::parse_model(a.model);
  if (!model) return model.error();
  auto obs = fitting::ObsMapReader::open(a.obsmap);
  if (!obs) return obs.error();
  fitting::MapFitOptions options;
  options.model = model.value();
  options.threads = a.threads;
  ProgressLine progress;
  options.on_progress = [&progress](const fitting::MapFitProgress& p) {
    progress.update(p.texels_done, p.texels_total, "  texels %d/%d", p.texels_done, p.texels_total);
  };
  auto map = fitting::fit_parameter_map(obs.value(), options);
  progress.finish();
  if (!map) return map.error();
  VDRIG_TRY(map->write(a.out));
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
    auto* cmd = rti->add_subcommand("import", "photographs + .lp light list -> observation-map file");
    cmd->add_option("stack", a->stack, "the .lp file, or a folder holding exactly one")->required();
    cmd->add_option("--out", a->out, "observation-map file to write (.vdobs)")->required();
    cmd->add_option("--crop", a->crop, "x,y,w,h in image pixels from the top-left corner");
    cmd->add_option("--response", a->response, "8/16-bit codes to radiance: sRGB | linear | a response JSON file")
        ->capture_default_str();
    cmd->add_option("--compression", a->compression, "observation map: none | zstd")
        ->check(CLI::IsMember({"none", "zstd"}))
        ->capture_default_str();
    cmd->add_option("--tile", a->tile, "observation map: texels per tile side")->capture_default_str();
    cmd->add_option("--zstd-level", a->zstd_level, "observation map: zstd level (negative: zstd's fast levels)")
        ->capture_default_str();
    cmd->callback([a] { finish(run_import(*a)); });
  }
  {
    auto a = std::make_shared<FitArgs>();
    auto* cmd = rti->add_subcommand("fit", "fit an imported stack -> parameter map (EXR) with RMS and leave-one-out");
    cmd->add_option("obsmap", a->obsmap, "observation-map file (vdrig rti import)")->required();
    cmd->add_option("--model", a->model, fitting::model_registry().syntax())->capture_default_str();
    cmd->add_option("--out", a->out, "parameter map to write (.exr)")->required();
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

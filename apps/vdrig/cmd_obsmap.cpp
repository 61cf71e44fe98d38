// `vdrig obsmap build SESSION --res SxT`: stream a session's HDR views into an observation-map file;
// `vdrig obsmap info FILE` and `vdrig obsmap plot FILE --texel S,T --out plot.png`: inspect one (fitting/
// obsmap_file.hpp, format in docs/obsmap.md) a tile at a time, whatever its size.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "mpi_job.hpp"
#include "progress.hpp"
#include "vdrig/cluster/distributed_obsmap.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/pipeline/pipeline.hpp"

namespace vdrig::app {
namespace {

Error usage(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }

const char* compression_name(fitting::ObsCompression c) {
  return c == fitting::ObsCompression::kZstd ? "zstd" : "none";
}

struct BuildArgs {
  std::string session, resolution = "256x256", out, compression = "zstd";
  int tile = 32;
  bool mpi = false;  // one rank of `mpirun -n N vdrig obsmap build ... --mpi`: tile rows split over the ranks
};

Status run_build(const BuildArgs& a) {
  auto res = parse_resolution(a.resolution);
  if (!res) return res.error();
  fitting::ObsFileOptions file;
  file.tile_size = a.tile;
  file.compression = a.compression == "none" ? fitting::ObsCompression::kNone : fitting::ObsCompression::kZstd;
  std::string why;
  if (!file.is_valid(&why)) return usage(why);
  auto session = capture::Session::open(a.session);
  if (!session) return session.error();
  pipeline::ObsMapBuildOptions options;
  options.file = file;
  ProgressLine progress;
  options.on_view = [&progress](int done, int total) { progress.update(done, total, "  views %d/%d", done, total); };
  const std::filesystem::path out =
      a.out.empty() ? session->layout().obsmap_file(res->first, res->second) : std::filesystem::path(a.out);
  if (a.mpi) {
    auto comm = cluster::world();
    if (!comm) return comm.error();
    if (comm.value()->rank() != 0) options.on_view = nullptr;
    const auto build_part = [&](const fitting::ObsFileOptions& rows, const std::filesystem::path& part) {
      pipeline::ObsMapBuildOptions mine = options;
      mine.file = rows;
      return pipeline::build_session_obsmap_file(session.value(), res->first, res->second, part, mine);
    };
    const Status built = cluster::build_obsmap_distributed(*comm.value(), res->second, file, out, build_part);
    progress.finish();
    VDRIG_TRY(built);
    if (comm.value()->rank() == 0) std::printf("wrote %s on %d MPI ranks\n", out.c_str(), comm.value()->size());
    return Status::ok();
  }
  const Status built = pipeline::build_session_obsmap_file(session.value(), res->first, res->second, out, options);
  progress.finish();
  VDRIG_TRY(built);
  std::printf("wrote %s\n", out.c_str());
  return Status::ok();
}

Status run_info(const std::string& path) {
  auto reader = fitting::ObsMapReader::open(path);
  if (!reader) return reader.error();
  const fitting::ObsFileHeader& h = reader->header();
  std::printf("%s: observation map, format version %u\n", path.c_str(), h.version);
  std::printf("  texels        %d x %d over %.1f x %.1f mm (%.3f x %.3f mm per texel)\n", h.spec.texels_s,
              h.spec.texels_t, h.spec.width_mm, h.spec.height_mm, h.spec.width_mm / h.spec.texels_s,
              h.spec.height_mm / h.spec.texels_t);
  std::printf("  views         %d\n", h.views);
  std::printf("  tiles         %d x %d of %d texels\n", h.tiles_s, h.tiles_t, h.tile_size);
  std::printf(
      "  compression   %s: tiles %.1f MB stored, %.1f MB raw (ratio %.2f); file %.1f MB\n",
      compression_name(h.compression), h.stored_tile_bytes / 1e6, h.raw_tile_bytes / 1e6,
      h.stored_tile_bytes ? static_cast<double>(h.raw_tile_bytes) / static_cast<double>(h.stored_tile_bytes) : 0.0,
      h.file_bytes / 1e6);
  if (h.views == 0) return Status::ok();

  // Statistics over every observation, one tile in memory at a time.
  uint64_t by_flag[7] = {};
  uint64_t other_flags = 0;
  int min_valid = std::numeric_limits<int>::max(), max_valid = 0;
  uint64_t texels_without = 0, sum_valid = 0;
  std::vector<uint64_t> valid_per_view(h.views, 0);
  for (int tt = 0; tt < reader->tiles_t(); ++tt)
    for (int ts = 0; ts < reader->tiles_s(); ++ts) {
      auto tile = reader->read_tile(ts, tt);
      if (!tile) return tile.error();
      for (int t = tile->t0(); t < tile->t0() + tile->height(); ++t)
        for (int s = tile->s0(); s < tile->s0() + tile->width(); ++s) {
          int valid = 0;
          for (int v = 0; v < h.views; ++v) {
            const uint8_t f = tile->flag(s, t, v);
            if (f == fitting::kObsValid) {
              ++valid;
              ++valid_per_view[v];
            }
            const int bit = f == 0 ? 0 : 1 + std::countr_zero(static_cast<unsigned>(f));
            if (bit < 7 && (f & (f - 1)) == 0)
              ++by_flag[bit];
            else
              ++other_flags;
          }
          min_valid = std::min(min_valid, valid);
          max_valid = std::max(max_valid, valid);
          sum_valid += valid;
          if (valid == 0) ++texels_without;
        }
    }
  const double total = static_cast<double>(h.spec.texels_s) * h.spec.texels_t * h.views;
  const double texels = static_cast<double>(h.spec.texels_s) * h.spec.texels_t;
  const char* names[7] = {"valid",         "outside image", "back-facing",     "clipped",
                          "excluded view", "occluded",      "coarse (grazing)"};
  std::printf("  observations  %.0f\n", total);
  for (int i = 0; i < 7; ++i)
    std::printf("    %-14s %12llu  %6.2f%%\n", names[i], static_cast<unsigned long long>(by_flag[i]),
                100.0 * static_cast<double>(by_flag[i]) / total);
  if (other_flags) std::printf("    %-14s %12llu\n", "other flags", static_cast<unsigned long long>(other_flags));
  std::printf("  valid per texel: min %d, mean %.1f, max %d; %llu texels have none\n", min_valid,
              static_cast<double>(sum_valid) / texels, max_valid, static_cast<unsigned long long>(texels_without));
  const auto [lo, hi] = std::minmax_element(valid_per_view.begin(), valid_per_view.end());
  std::printf("  texels seen per view: min %llu (view %ld), max %llu (view %ld) of %.0f\n",
              static_cast<unsigned long long>(*lo), static_cast<long>(lo - valid_per_view.begin()),
              static_cast<unsigned long long>(*hi), static_cast<long>(hi - valid_per_view.begin()), texels);
  return Status::ok();
}

/// Polar plot of one texel's observations over the hemisphere: radius proportional to zenith (centre = normal,
/// rim = horizon), angle = azimuth (surface +x to the right, +y up), colour = radiance scaled to the texel's
/// brightest valid observation (gamma 2.2). Unusable observations are grey rings.
Status run_plot(const std::string& path, const std::string& texel, const std::string& out, int size_px) {
  int s = 0, t = 0;
  char comma = 0;
  std::istringstream ts(texel);
  if (!(ts >> s >> comma >> t) || comma != ',' || !ts.eof()) return usage("--texel wants S,T; got '" + texel + "'");
  if (size_px < 128 || size_px > 8192) return usage("--size must be in [128, 8192]");
  auto reader = fitting::ObsMapReader::open(path);
  if (!reader) return reader.error();
  auto tile = reader->read_tile_of_texel(s, t);
  if (!tile) return tile.error();
  const int views = reader->views();

  float peak = 0.0f;
  for (int v = 0; v < views; ++v) {
    Eigen::Vector3f rgb, dir;
    if (tile->observation(s, t, v, &rgb, &dir) == fitting::kObsValid) peak = std::max(peak, rgb.maxCoeff());
  }
  cv::Mat canvas(size_px, size_px, CV_8UC3, cv::Scalar(24, 24, 24));
  const cv::Point2d c(size_px / 2.0, size_px / 2.0 + size_px * 0.01);
  const double R = size_px * 0.40;
  const cv::Scalar grid(90, 90, 90), text(220, 220, 220);
  const double font = size_px / 1200.0;
  for (const int zen : {30, 60, 90})
    cv::circle(canvas, c, static_cast<int>(std::lround(R * zen / 90.0)), grid, 1, cv::LINE_AA);
  for (int az = 0; az < 360; az += 45) {
    const double a = deg_to_rad(az);
    const cv::Point2d rim(c.x + R * std::cos(a), c.y - R * std::sin(a));
    cv::line(canvas, c, rim, grid, 1, cv::LINE_AA);
    const cv::Point2d label(c.x + (R + size_px * 0.035) * std::cos(a) - size_px * 0.02,
                            c.y - (R + size_px * 0.035) * std::sin(a) + size_px * 0.01);
    cv::putText(canvas, std::to_string(az), label, cv::FONT_HERSHEY_SIMPLEX, font, text, 1, cv::LINE_AA);
  }
  for (const int zen : {30, 60})
    cv::putText(canvas, std::to_string(zen), cv::Point2d(c.x + R * zen / 90.0 + 3, c.y - 3), cv::FONT_HERSHEY_SIMPLEX,
                font * 0.8, grid, 1, cv::LINE_AA);

  const int dot = std::max(3, size_px / 70);
  int valid = 0;
  // Unusable ones first so valid dots are drawn over them.
  for (const bool draw_valid : {false, true})
    for (int v = 0; v < views; ++v) {
      Eigen::Vector3f rgb, dir;
      const uint8_t f = tile->observation(s, t, v, &rgb, &dir);
      if ((f == fitting::kObsValid) != draw_valid || !(dir.norm() > 0.5f)) continue;
      const double zenith = std::acos(std::clamp(static_cast<double>(dir.z()), -1.0, 1.0));
      const double azimuth = std::atan2(dir.y(), dir.x());
      const double r = R * std::min(zenith, kPi / 2) / (kPi / 2);
      const cv::Point p(static_cast<int>(std::lround(c.x + r * std::cos(azimuth))),
                        static_cast<int>(std::lround(c.y - r * std::sin(azimuth))));
      if (!draw_valid) {
        cv::circle(canvas, p, dot / 2, cv::Scalar(110, 110, 110), 1, cv::LINE_AA);
        continue;
      }
      ++valid;
      auto tone = [&](float x) {
        const double n = peak > 0 ? std::clamp(static_cast<double>(x) / peak, 0.0, 1.0) : 0.0;
        return std::pow(n, 1.0 / 2.2) * 255.0;
      };
      cv::circle(canvas, p, dot, cv::Scalar(tone(rgb.z()), tone(rgb.y()), tone(rgb.x())), cv::FILLED, cv::LINE_AA);
      cv::circle(canvas, p, dot, cv::Scalar(200, 200, 200), 1, cv::LINE_AA);
    }
  char title[256];
  std::snprintf(title, sizeof title, "texel (%d, %d): %d valid of %d views, peak radiance %.4g", s, t, valid, views,
                static_cast<double>(peak));
  cv::putText(canvas, title, cv::Point(size_px / 40, size_px / 24), cv::FONT_HERSHEY_SIMPLEX, font * 1.1, text, 1,
              cv::LINE_AA);
  cv::putText(canvas, "radius: zenith (deg), angle: azimuth (deg), colour: radiance",
              cv::Point(size_px / 40, size_px - size_px / 60), cv::FONT_HERSHEY_SIMPLEX, font * 0.9, grid, 1,
              cv::LINE_AA);
  VDRIG_TRY(write_png(out, canvas));
  std::printf("texel (%d, %d): %d valid observations of %d views -> %s\n", s, t, valid, views, out.c_str());
  return Status::ok();
}

const CommandRegistrar registrar([](CLI::App& root) {
  auto* obsmap = root.add_subcommand("obsmap", "build and inspect observation-map files (docs/obsmap.md)");
  obsmap->require_subcommand(1);
  {
    auto* cmd = obsmap->add_subcommand("build", "stream a session's HDR views into an observation-map file");
    auto a = std::make_shared<BuildArgs>();
    cmd->add_option("session", a->session, "session folder (with hdr/ merged)")->required();
    cmd->add_option("--res", a->resolution, "texels, SxT")->capture_default_str();
    cmd->add_option("--out", a->out, "file to write (default SESSION/obsmap/<res>.vdobs)");
    cmd->add_option("--tile", a->tile, "texels per tile side")->capture_default_str();
    cmd->add_option("--compression", a->compression, "zstd | none")
        ->capture_default_str()
        ->check(CLI::IsMember({"zstd", "none"}));
    cmd->add_flag("--mpi", a->mpi,
                  "one rank of an MPI job (mpirun -n N vdrig obsmap build ... --mpi): each rank samples its tile rows "
                  "into a part, rank 0 joins them (docs/scale.md)");
    cmd->callback([a] { finish_job(run_build(*a)); });
  }
  {
    auto* cmd = obsmap->add_subcommand("info", "header, sizes and valid-observation statistics");
    auto file = std::make_shared<std::string>();
    cmd->add_option("file", *file, "observation-map file")->required();
    cmd->callback([file] { finish(run_info(*file)); });
  }
  {
    auto* cmd = obsmap->add_subcommand("plot", "one texel's observations on the hemisphere (polar plot, PNG)");
    struct Args {
      std::string file, texel, out = "plot.png";
      int size_px = 600;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("file", a->file, "observation-map file")->required();
    cmd->add_option("--texel", a->texel, "texel S,T")->required();
    cmd->add_option("--out", a->out, "PNG to write")->capture_default_str();
    cmd->add_option("--size", a->size_px, "image side, pixels")->capture_default_str();
    cmd->callback([a] { finish(run_plot(a->file, a->texel, a->out, a->size_px)); });
  }
});

}  // namespace
}  // namespace vdrig::app

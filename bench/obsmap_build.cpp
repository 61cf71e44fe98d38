// Out-of-core observation map: stream a 512 x 512-texel map over 289 views (1.9 GB of observations, more than the
// memory budget) to a file with ObsMapWriter, and report the time of each phase and the peak resident set size.
// Target: peak RSS < 1 GB (the writer holds one view's and one tile's observations, not the map). Then fits HSH-9
// from the file tile by tile (fit_parameter_map(ObsMapReader)): the whole out-of-core path in bounded memory.
//
// Usage: bench_obsmap_build [OUT_DIR=/tmp] [none|zstd] [TEXELS=512] [VIEWS=289] [--keep]
// The views are synthetic 640 x 480 HDR images (smooth radiance, a little different per view) from poses spread
// over the hemisphere (golden-angle spiral in cos(zenith), zenith <= 80 deg) through rig::surface_pose.
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/rig/kinematics.hpp"

using namespace vdrig;

namespace {
double now_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;  // kB on Linux
}
}  // namespace

int main(int argc, char** argv) {
  std::filesystem::path out_dir = "/tmp";
  fitting::ObsFileOptions opt;
  int texels = 512, views = 289;
  bool keep = false;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--keep") {
      keep = true;
    } else if (positional == 0) {
      out_dir = a, ++positional;
    } else if (positional == 1) {
      opt.compression = a == "none" ? fitting::ObsCompression::kNone : fitting::ObsCompression::kZstd, ++positional;
    } else if (positional == 2) {
      texels = std::atoi(a.c_str()), ++positional;
    } else {
      views = std::atoi(a.c_str());
    }
  }
  const std::filesystem::path path = out_dir / "bench_obsmap_build.vdobs";
  const CameraModel cam{640, 480, 1000.0, 1000.0, 319.5, 239.5, -0.08, 0.02, 0.0, 0.0, 0.0};
  const fitting::ObservationMapSpec spec{texels, texels, 1000.0, 1000.0};
  std::printf("obsmap build: %dx%d texels x %d views (%.2f GB of observations in memory), %dx%d images, %s\n", texels,
              texels, views, 25.0 * texels * texels * views / 1e9, cam.width, cam.height,
              opt.compression == fitting::ObsCompression::kZstd ? "zstd" : "uncompressed");

  const double t0 = now_s();
  auto writer = fitting::ObsMapWriter::create(path, spec, views, opt);
  if (!writer) {
    std::fprintf(stderr, "%s\n", writer.error().describe().c_str());
    return 1;
  }
  const double cos_max = std::cos(deg_to_rad(80.0));
  double image_s = 0;
  fitting::ViewInput in;
  in.camera = cam;
  in.radiance_bgr.create(cam.height, cam.width, CV_32FC3);
  for (int v = 0; v < views; ++v) {
    const double cz = 1.0 - (1.0 - cos_max) * (v + 0.5) / views;
    const double azimuth = std::fmod(v * 2.399963229728653, 2 * kPi);
    in.pose = rig::surface_pose({}, PanTilt{kPi / 2 - azimuth, std::acos(cz)});
    const double ti = now_s();
    const float base = 0.5f + 0.4f * static_cast<float>(cz);
    for (int y = 0; y < cam.height; ++y) {
      auto* row = in.radiance_bgr.ptr<cv::Vec3f>(y);
      for (int x = 0; x < cam.width; ++x)
        row[x] = cv::Vec3f(base * 0.8f, base * (1.0f + 1e-4f * y), base * (1.0f + 2e-4f * x));
    }
    image_s += now_s() - ti;
    const Status st = writer->add_view(v, in);
    if (!st) {
      std::fprintf(stderr, "%s\n", st.describe().c_str());
      return 1;
    }
  }
  const double t1 = now_s();
  const Status st = writer->finish();
  if (!st) {
    std::fprintf(stderr, "%s\n", st.describe().c_str());
    return 1;
  }
  const double t2 = now_s();

  auto reader = fitting::ObsMapReader::open(path);
  if (!reader) {
    std::fprintf(stderr, "%s\n", reader.error().describe().c_str());
    return 1;
  }
  const double t3 = now_s();
  long valid = 0;
  for (int tt = 0; tt < reader->tiles_t(); ++tt)
    for (int ts = 0; ts < reader->tiles_s(); ++ts) {
      auto tile = reader->read_tile(ts, tt);
      if (!tile) {
        std::fprintf(stderr, "%s\n", tile.error().describe().c_str());
        return 1;
      }
      for (int t = tile->t0(); t < tile->t0() + tile->height(); ++t)
        for (int s = tile->s0(); s < tile->s0() + tile->width(); ++s) valid += tile->texel(s, t).size();
    }
  const double t4 = now_s();
  const double rss_build_mb = peak_rss_mb();

  // Out of core end to end: fit HSH-9 (hsh:3) from the file a tile per thread at a time, as `vdrig fit` does.
  fitting::MapFitOptions fit;
  fit.model = fitting::parse_model("hsh:3").value();
  fit.threads = 2;
  auto map = fitting::fit_parameter_map(reader.value(), fit);
  if (!map) {
    std::fprintf(stderr, "%s\n", map.error().describe().c_str());
    return 1;
  }
  const double t5 = now_s();
  const auto& h = reader->header();
  std::printf("  views (sample + spill): %.1f s (%.1f ms/view, of which synthetic images %.1f s)\n", t1 - t0,
              1e3 * (t1 - t0) / views, image_s);
  std::printf("  finish (transpose + write): %.1f s\n", t2 - t1);
  std::printf("  total build: %.1f s\n", t2 - t0);
  std::printf("  read back every tile: %.1f s, %ld valid observations (%.1f per texel)\n", t4 - t3, valid,
              static_cast<double>(valid) / (static_cast<double>(texels) * texels));
  std::printf("  file: %.1f MB (tiles raw %.1f MB, ratio %.2f)\n", h.file_bytes / 1e6, h.raw_tile_bytes / 1e6,
              static_cast<double>(h.raw_tile_bytes) / static_cast<double>(h.stored_tile_bytes));
  std::printf("  peak RSS after build and read-back: %.0f MB (target < 1024 MB)\n", rss_build_mb);
  std::printf("  fit hsh:3 from the file, tile by tile, 2 threads: %.1f s; peak RSS %.0f MB\n", t5 - t4, peak_rss_mb());
  if (!keep) std::filesystem::remove(path);
  return peak_rss_mb() < 1024.0 ? 0 : 2;
}

// ObsMapWriter: views spilled as they come, then transposed tile by tile into the file (docs/obsmap.md, "Writing").
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <opencv2/core/utility.hpp>

#include "obsmap_checksum.hpp"
#include "obsmap_format.hpp"
#include "obsmap_zstd.hpp"
#include "positional_file_io.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::fitting {
namespace fs = std::filesystem;
using namespace obsmap_format;

namespace {

constexpr int kSpillZstdLevel = 1;  // the spill is read once: favour speed

/// write_at with the test hook of ObsFileOptions (a failed hook is the write's failure).
Status hooked_write_at(int fd, const fs::path& path, const void* data, size_t n, uint64_t offset,
                       const ObsFileOptions& opt) {
  if (opt.before_write) VDRIG_TRY(opt.before_write(path, n));
  return write_at(fd, path, data, n, offset);
}

}  // namespace

bool ObsFileOptions::is_valid(std::string* why) const {
  if (tile_size < 1 || tile_size > kMaxTileSize) {
    if (why) *why = "tile size must be in [1, " + std::to_string(kMaxTileSize) + "], got " + std::to_string(tile_size);
    return false;
  }
  if (compression != ObsCompression::kNone && compression != ObsCompression::kZstd) {
    if (why) *why = "unknown compression";
    return false;
  }
  if (compression == ObsCompression::kZstd &&
      (zstd_level < kMinZstdLevel || zstd_level == 0 || zstd_level > zstd_max_level())) {
    if (why)
      *why = "zstd level must be in [" + std::to_string(kMinZstdLevel) + ", -1] or [1, " +
             std::to_string(zstd_max_level()) + "]";
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------------------------
// Writer

struct ObsMapWriter::Impl {
  fs::path path, tmp_path, spill_path;
  ObservationMapSpec spec;
  int views = 0;
  ObsFileOptions opt;
  TileGrid grid;
  UniqueFd out, spill;
  uint64_t spill_end = 0;
  struct Chunk {
    uint64_t offset = 0;
    uint64_t bytes = 0;
  };
  std::vector<Chunk> chunks;  // [view][tile]: where the view's part of the tile is in the spill file
  std::vector<bool> added;
  bool finished = false;
  // One view's observations, map texel order (t * S + s).
  std::vector<float> rgb, dir;
  std::vector<uint8_t> flags;
  ZstdTileCompressor compressor;
  ZstdTileDecompressor decompressor;

  ~Impl() {
    if (!finished && !tmp_path.empty()) ::unlink(tmp_path.c_str());
  }

  /// A part of a file (ObsFileOptions::first_tile_row/end_tile_row): only its tile rows are sampled and written.
  bool partial() const { return opt.end_tile_row >= 0; }
  bool owns_tile(int k) const {
    const int tt = k / grid.tiles_s;
    return !partial() || (tt >= opt.first_tile_row && tt < opt.end_tile_row);
  }

  Status begin_view(int view) {
    if (finished) return make_error(ErrorCode::kInvalidArgument, "observation-map writer already finished");
    if (view < 0 || view >= views)
      return make_error(ErrorCode::kInvalidArgument,
                        "view " + std::to_string(view) + " out of range [0, " + std::to_string(views) + ")");
    if (added[view]) return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(view) + " added twice");
    return Status::ok();
  }

  /// Cuts the current view buffer into tiles and appends them (one write) to the spill file.
  Status spill_view(int view) {
    std::vector<char> block, raw, z;
    std::vector<float> trgb, tdir;
    std::vector<uint8_t> tflags;
    for (int k = 0; k < grid.count(); ++k) {
      if (!owns_tile(k)) continue;
      const int ts = k % grid.tiles_s, tt = k / grid.tiles_s;
      const int w = grid.width(ts), h = grid.height(tt);
      const size_t n = static_cast<size_t>(w) * h;
      trgb.resize(3 * n);
      tdir.resize(3 * n);
      tflags.resize(n);
      size_t j = 0;
      for (int t = tt * grid.tile; t < tt * grid.tile + h; ++t)
        for (int s = ts * grid.tile; s < ts * grid.tile + w; ++s, ++j) {
          const size_t i = static_cast<size_t>(t) * spec.texels_s + s;
          std::memcpy(&trgb[3 * j], &rgb[3 * i], 12);
          std::memcpy(&tdir[3 * j], &dir[3 * i], 12);
          tflags[j] = flags[i];
        }
      pack(raw, trgb.data(), tdir.data(), tflags.data(), n);
      const std::vector<char>* stored = &raw;
      if (opt.compression == ObsCompression::kZstd) {
        compressor.compress(raw, std::min(kSpillZstdLevel, opt.zstd_level), z);
        stored = &z;
      }
      chunks[static_cast<size_t>(view) * grid.count() + k] = {spill_end + block.size(), stored->size()};
      block.insert(block.end(), stored->begin(), stored->end());
    }
    VDRIG_TRY(hooked_write_at(spill.get(), spill_path, block.data(), block.size(), spill_end, opt));
    spill_end += block.size();
    added[view] = true;
    return Status::ok();
  }

  /// Reads view `view`'s part of tile k back from the spill file into `raw`.
  Status read_chunk(int view, int k, std::vector<char>& raw, std::vector<char>& z) {
    const Chunk& c = chunks[static_cast<size_t>(view) * grid.count() + k];
    const size_t n = raw_bytes(grid.texels(k));
    raw.resize(n);
    if (opt.compression == ObsCompression::kNone) return read_at(spill.get(), spill_path, raw.data(), n, c.offset);
    z.resize(c.bytes);
    VDRIG_TRY(read_at(spill.get(), spill_path, z.data(), z.size(), c.offset));
    if (!decompressor.decompress(z, n, raw))
      return make_error(ErrorCode::kIo, "spill file " + spill_path.string() + " read back damaged");
    return Status::ok();
  }

  Status finish() {
    if (finished) return make_error(ErrorCode::kInvalidArgument, "observation-map writer already finished");
    for (int v = 0; v < views; ++v)
      if (!added[v]) return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(v) + " was never added");
    std::vector<char> header(kHeaderBytes, 0);
    VDRIG_TRY(hooked_write_at(out.get(), tmp_path, header.data(), header.size(), 0, opt));
    uint64_t offset = kHeaderBytes;
    std::vector<char> index(kIndexEntryBytes * grid.count(), 0);
    std::vector<char> raw, z, payload;
    std::vector<float> trgb, tdir;
    std::vector<uint8_t> tflags;
    if (opt.compression == ObsCompression::kZstd) {
      compressor.set_file_tile_parameters(opt.zstd_level);
    }
    for (int k = 0; k < grid.count(); ++k) {
      if (!owns_tile(k)) continue;  // a part leaves other rows' index entries zero
      // Transpose: the spill holds [view][texel]; the tile stores [texel][view].
      const size_t nt = grid.texels(k), V = static_cast<size_t>(views);
      trgb.resize(3 * nt * V);
      tdir.resize(3 * nt * V);
      tflags.resize(nt * V);
      for (int v = 0; v < views; ++v) {
        VDRIG_TRY(read_chunk(v, k, raw, z));
        const char* r = raw.data();
        for (size_t j = 0; j < nt; ++j) {
          const size_t o = j * V + v;
          std::memcpy(&trgb[3 * o], r + 12 * j, 12);
          std::memcpy(&tdir[3 * o], r + 12 * nt + 12 * j, 12);
          tflags[o] = static_cast<uint8_t>(r[24 * nt + j]);
        }
      }
      pack(payload, trgb.data(), tdir.data(), tflags.data(), nt * V);
      const std::vector<char>* stored = &payload;
      if (opt.compression == ObsCompression::kZstd) {
        compressor.compress_file_tile(payload, z);
        stored = &z;
      }
      VDRIG_TRY(hooked_write_at(out.get(), tmp_path, stored->data(), stored->size(), offset, opt));
      put<uint64_t>(index, kIndexEntryBytes * k, offset);
      put<uint64_t>(index, kIndexEntryBytes * k + 8, stored->size());
      put<uint64_t>(index, kIndexEntryBytes * k + 16, obsmap_hash64(stored->data(), stored->size()));
      offset += stored->size();
    }
    VDRIG_TRY(hooked_write_at(out.get(), tmp_path, index.data(), index.size(), offset, opt));

    header = make_header(partial() ? kPartMagic : kMagic, spec, views, grid, opt.compression, offset, index);
    if (partial()) {
      put<uint32_t>(header, kAtPartFirstRow, static_cast<uint32_t>(opt.first_tile_row));
      put<uint32_t>(header, kAtPartEndRow, static_cast<uint32_t>(opt.end_tile_row));
      put<uint64_t>(header, kAtHeaderChecksum, obsmap_hash64(header.data(), kAtHeaderChecksum));
    }
    VDRIG_TRY(hooked_write_at(out.get(), tmp_path, header.data(), header.size(), 0, opt));

    out.reset();
    spill.reset();
    // fsync, rename over `path` (refused when it is a link or not a regular file), fsync of the folder.
    VDRIG_TRY(commit_temporary(tmp_path, path));
    finished = true;
    log::get("fitting")->info("observation map {} written: {}x{} texels x {} views, {} tiles, {:.1f} MB", path.string(),
                              spec.texels_s, spec.texels_t, views, grid.count(), (offset + index.size()) / 1e6);
    return Status::ok();
  }
};
Result<ObsMapWriter> ObsMapWriter::create(const fs::path& path, const ObservationMapSpec& spec, int views,
                                          const ObsFileOptions& options) {
  std::string why;
  if (!spec.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  if (!options.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  if (views < 0 || views > kMaxViews)
    return make_error(ErrorCode::kInvalidArgument, "view count out of range: " + std::to_string(views));
  if (spec.texels_s > kMaxTexelsPerSide || spec.texels_t > kMaxTexelsPerSide)
    return make_error(ErrorCode::kInvalidArgument, "observation map too large");
  if (const std::string why_big = tile_too_large(options.tile_size, spec.texels_s, spec.texels_t, views);
      !why_big.empty())
    return make_error(ErrorCode::kInvalidArgument, why_big + ": use a smaller tile size");
  const int tiles_t = ceil_div(spec.texels_t, options.tile_size);
  if (options.end_tile_row >= 0 && !(options.first_tile_row >= 0 && options.first_tile_row <= options.end_tile_row &&
                                     options.end_tile_row <= tiles_t))
    return make_error(ErrorCode::kInvalidArgument, "tile rows [" + std::to_string(options.first_tile_row) + ", " +
                                                       std::to_string(options.end_tile_row) + ") not within [0, " +
                                                       std::to_string(tiles_t) + "]");
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->spec = spec;
  impl->views = views;
  impl->opt = options;
  impl->grid = TileGrid(spec.texels_s, spec.texels_t, options.tile_size);
  impl->chunks.resize(static_cast<size_t>(views) * impl->grid.count());
  impl->added.assign(views, false);
  const size_t n = static_cast<size_t>(spec.texels_s) * spec.texels_t;
  impl->rgb.resize(3 * n);
  impl->dir.resize(3 * n);
  impl->flags.resize(n);

  auto out = create_temporary_beside(path, &impl->tmp_path);
  if (!out) return out.error();
  impl->out = std::move(out.value());
  const fs::path spill_dir =
      options.spill_dir.empty() ? (path.parent_path().empty() ? fs::path(".") : path.parent_path()) : options.spill_dir;
  auto spill = create_anonymous_file(spill_dir, &impl->spill_path);
  if (!spill) return spill.error();
  impl->spill = std::move(spill.value());
  return ObsMapWriter(std::move(impl));
}

ObsMapWriter::ObsMapWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ObsMapWriter::ObsMapWriter(ObsMapWriter&&) noexcept = default;
ObsMapWriter& ObsMapWriter::operator=(ObsMapWriter&&) noexcept = default;
ObsMapWriter::~ObsMapWriter() = default;
const ObservationMapSpec& ObsMapWriter::spec() const { return impl_->spec; }
int ObsMapWriter::views() const { return impl_->views; }

Status ObsMapWriter::add_view(int view, const ViewInput& input) {
  VDRIG_TRY(impl_->begin_view(view));
  if (input.radiance_bgr.type() != CV_32FC3)
    return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(view) + ": radiance must be CV_32FC3");
  if (!input.clip_mask.empty() &&
      (input.clip_mask.type() != CV_8UC1 || input.clip_mask.size() != input.radiance_bgr.size()))
    return make_error(ErrorCode::kInvalidArgument,
                      "view " + std::to_string(view) + ": clip mask must be CV_8UC1 of the image's size");
  Impl& m = *impl_;
  const ObservationMapSpec& spec = m.spec;
  // A part samples only the texel rows of its tile rows.
  const int t_begin = m.partial() ? std::min(spec.texels_t, m.opt.first_tile_row * m.grid.tile) : 0;
  const int t_end = m.partial() ? std::min(spec.texels_t, m.opt.end_tile_row * m.grid.tile) : spec.texels_t;
  cv::parallel_for_(cv::Range(t_begin, t_end), [&](const cv::Range& rows) {
    for (int t = rows.start; t < rows.end; ++t)
      for (int s = 0; s < spec.texels_s; ++s) {
        const size_t i = static_cast<size_t>(t) * spec.texels_s + s;
        Eigen::Vector3f rgb, dir;
        m.flags[i] = observe_texel(spec, input, s, t, &rgb, &dir);
        std::memcpy(&m.rgb[3 * i], rgb.data(), 12);
        std::memcpy(&m.dir[3 * i], dir.data(), 12);
      }
  });
  return m.spill_view(view);
}

Status ObsMapWriter::add_view(int view, const ObservationMap& map) {
  VDRIG_TRY(impl_->begin_view(view));
  Impl& m = *impl_;
  const ObservationMapSpec& a = map.spec();
  if (a.texels_s != m.spec.texels_s || a.texels_t != m.spec.texels_t || a.width_mm != m.spec.width_mm ||
      a.height_mm != m.spec.height_mm || map.views() != m.views)
    return make_error(ErrorCode::kInvalidArgument, "in-memory map's spec or view count differs from the writer's");
  for (int t = 0; t < a.texels_t; ++t)
    for (int s = 0; s < a.texels_s; ++s) {
      const size_t i = static_cast<size_t>(t) * a.texels_s + s;
      Eigen::Vector3f rgb, dir;
      m.flags[i] = map.observation(s, t, view, &rgb, &dir);
      std::memcpy(&m.rgb[3 * i], rgb.data(), 12);
      std::memcpy(&m.dir[3 * i], dir.data(), 12);
    }
  return m.spill_view(view);
}

Status ObsMapWriter::add_shared_direction_view(int view, const cv::Mat& radiance_rgb, const Eigen::Vector3f& direction,
                                               const cv::Mat& clip_mask) {
  VDRIG_TRY(impl_->begin_view(view));
  Impl& m = *impl_;
  const ObservationMapSpec& spec = m.spec;
  if (radiance_rgb.type() != CV_32FC3 || radiance_rgb.cols != spec.texels_s || radiance_rgb.rows != spec.texels_t)
    return make_error(ErrorCode::kInvalidArgument,
                      "view " + std::to_string(view) + ": radiance must be CV_32FC3 of the map's texels");
  if (!clip_mask.empty() && (clip_mask.type() != CV_8UC1 || clip_mask.size() != radiance_rgb.size()))
    return make_error(ErrorCode::kInvalidArgument,
                      "view " + std::to_string(view) + ": clip mask must be CV_8UC1 of the image's size");
  for (int t = 0; t < spec.texels_t; ++t) {
    const size_t row = static_cast<size_t>(t) * spec.texels_s;
    std::memcpy(&m.rgb[3 * row], radiance_rgb.ptr<float>(t), 12 * static_cast<size_t>(spec.texels_s));
    for (int s = 0; s < spec.texels_s; ++s) {
      std::memcpy(&m.dir[3 * (row + s)], direction.data(), 12);
      m.flags[row + s] = !clip_mask.empty() && clip_mask.at<uint8_t>(t, s) ? kObsClipped : kObsValid;
    }
  }
  return m.spill_view(view);
}

Status ObsMapWriter::finish() { return impl_->finish(); }

Status write_obsmap_file(const ObservationMap& map, const fs::path& path, const ObsFileOptions& options) {
  auto w = ObsMapWriter::create(path, map.spec(), map.views(), options);
  if (!w) return w.error();
  for (int v = 0; v < map.views(); ++v) VDRIG_TRY(w->add_view(v, map));
  return w->finish();
}
}  // namespace vdrig::fitting

#include "vdrig/fitting/obsmap_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <opencv2/core/utility.hpp>

#include "vdrig/core/file_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::fitting {
namespace fs = std::filesystem;

// The format is little-endian (docs/obsmap.md); this implementation writes its native layout.
static_assert(std::endian::native == std::endian::little, "obsmap files are little-endian; add byte swapping here");

namespace {

constexpr char kMagic[8] = {'V', 'D', 'R', 'I', 'G', 'O', 'B', 'S'};
constexpr size_t kHeaderBytes = 128;
constexpr size_t kIndexEntryBytes = 24;
constexpr uint32_t kRecordLayout = 1;  // per tile: radiance f32x3, direction f32x3, flag u8 (planes, docs)
constexpr size_t kBytesPerObservation = 25;
constexpr int kMaxTileSize = 4096;
constexpr int kMaxTexelsPerSide = 1 << 20;
constexpr int kMaxViews = 1 << 20;
/// A tile is read whole (stored, raw, then its arrays): the reader refuses tiles larger than this uncompressed
/// (e.g. 32 x 32 texels x 20,000 views, or 128 x 128 x 1,300), so a header's dimensions cannot make it allocate
/// gigabytes; the writer refuses to write what the reader would refuse.
constexpr uint64_t kMaxTileRawBytes = uint64_t{512} << 20;
constexpr int kSpillZstdLevel = 1;  // the spill is read once: favour speed

/// 64-bit hash of a byte range (8 bytes at a time, murmur-style mixing): catches flipped bits and torn writes.
uint64_t hash64(const void* data, size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  uint64_t h = 0x9E3779B97F4A7C15ull ^ (n * 0xFF51AFD7ED558CCDull);
  auto mix = [](uint64_t k) {
    k *= 0x87C37B91114253D5ull;
    k = (k << 31) | (k >> 33);
    return k * 0x4CF5AD432745937Full;
  };
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    uint64_t k;
    std::memcpy(&k, p + i, 8);
    h ^= mix(k);
    h = ((h << 27) | (h >> 37)) * 5 + 0x52DCE729;
  }
  uint64_t tail = 0;
  for (size_t j = 0; i + j < n; ++j) tail |= static_cast<uint64_t>(p[i + j]) << (8 * j);
  h ^= mix(tail);
  h ^= h >> 33;
  h *= 0xFF51AFD7ED558CCDull;
  h ^= h >> 33;
  return h;
}

/// Whether a stored checksum matches. Fuzzing builds skip the comparison: a mutated input could never pass it, and
/// the fuzzer would never reach the size checks and the decompressor behind it (docs/fuzzing.md).
bool checksum_matches(uint64_t stored, const void* data, size_t n) {
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
  (void)stored, (void)data, (void)n;
  return true;
#else
  return stored == hash64(data, n);
#endif
}

template <typename T>
void put(std::vector<char>& buf, size_t at, T v) {
  std::memcpy(buf.data() + at, &v, sizeof(T));
}
template <typename T>
T get(const std::vector<char>& buf, size_t at) {
  T v;
  std::memcpy(&v, buf.data() + at, sizeof(T));
  return v;
}

/// Owns a file descriptor.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  Fd& operator=(Fd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = std::exchange(o.fd_, -1);
    }
    return *this;
  }
  ~Fd() { reset(); }
  int get() const { return fd_; }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

Error io_error(const std::string& what, const fs::path& path, int err) {
  return error_from_errno(err, what + " " + path.string());
}

Status write_at(int fd, const fs::path& path, const void* data, size_t n, uint64_t offset, const ObsFileOptions& opt) {
  if (opt.before_write) VDRIG_TRY(opt.before_write(path, n));
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, p, n, static_cast<off_t>(offset));
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error("writing", path, errno);
    }
    if (w == 0) return io_error("writing", path, ENOSPC);
    p += w;
    n -= static_cast<size_t>(w);
    offset += static_cast<uint64_t>(w);
  }
  return Status::ok();
}

/// Reads exactly n bytes at `offset`; a short read means the file is shorter than its header or index says.
Status read_at(int fd, const fs::path& path, void* data, size_t n, uint64_t offset) {
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (r < 0) {
      if (errno == EINTR) continue;
      return io_error("reading", path, errno);
    }
    if (r == 0)
      return make_error(ErrorCode::kCorrupt,
                        path.string() + " is truncated (ends before byte " + std::to_string(offset + n) + ")");
    p += r;
    n -= static_cast<size_t>(r);
    offset += static_cast<uint64_t>(r);
  }
  return Status::ok();
}

int ceil_div(int a, int b) { return (a + b - 1) / b; }

/// Geometry of the tiles of a map, shared by the writer and the reader.
struct TileGrid {
  int S = 0, T = 0, tile = 1, tiles_s = 0, tiles_t = 0;
  TileGrid() = default;
  TileGrid(int s, int t, int tile_size)
      : S(s), T(t), tile(tile_size), tiles_s(ceil_div(s, tile_size)), tiles_t(ceil_div(t, tile_size)) {}
  int count() const { return tiles_s * tiles_t; }
  int width(int ts) const { return std::min(tile, S - ts * tile); }
  int height(int tt) const { return std::min(tile, T - tt * tile); }
  size_t texels(int k) const { return static_cast<size_t>(width(k % tiles_s)) * height(k / tiles_s); }
};

/// Raw (uncompressed) layout of n observations: radiance (3n f32), direction (3n f32), flags (n u8).
size_t raw_bytes(size_t n) { return n * kBytesPerObservation; }

/// Why a map's largest tile is more than a reader may allocate (kMaxTileRawBytes), or "" when it is not.
std::string tile_too_large(int tile_size, int texels_s, int texels_t, int views) {
  const uint64_t texels = static_cast<uint64_t>(std::min(tile_size, texels_s)) * std::min(tile_size, texels_t);
  if (raw_bytes(texels * static_cast<uint64_t>(views)) <= kMaxTileRawBytes) return "";
  return "a tile of " + std::to_string(texels) + " texels x " + std::to_string(views) +
         " views exceeds the reader's limit of " + std::to_string(kMaxTileRawBytes >> 20) + " MiB per tile";
}

void pack(std::vector<char>& out, const float* rgb, const float* dir, const uint8_t* flags, size_t n) {
  out.resize(raw_bytes(n));
  // A map of no views has empty tiles, and memcpy from a null pointer is undefined even for 0 bytes.
  if (n == 0) return;
  std::memcpy(out.data(), rgb, 12 * n);
  std::memcpy(out.data() + 12 * n, dir, 12 * n);
  std::memcpy(out.data() + 24 * n, flags, n);
}

constexpr char kPartMagic[8] = {'V', 'D', 'R', 'I', 'G', 'O', 'B', 'P'};

/// The 128-byte header of a file (magic kMagic) or part (kPartMagic; its tile rows are added by the caller).
std::vector<char> make_header(const char* magic, const ObservationMapSpec& spec, int views, const TileGrid& grid,
                              ObsCompression compression, uint64_t index_offset, const std::vector<char>& index) {
  std::vector<char> header(kHeaderBytes, 0);
  std::memcpy(header.data(), magic, 8);
  put<uint32_t>(header, 8, kObsFileVersion);
  put<uint32_t>(header, 12, kHeaderBytes);
  put<int32_t>(header, 16, spec.texels_s);
  put<int32_t>(header, 20, spec.texels_t);
  put<int32_t>(header, 24, views);
  put<int32_t>(header, 28, grid.tile);
  put<double>(header, 32, spec.width_mm);
  put<double>(header, 40, spec.height_mm);
  put<uint32_t>(header, 48, static_cast<uint32_t>(compression));
  put<uint32_t>(header, 52, kRecordLayout);
  put<uint32_t>(header, 56, static_cast<uint32_t>(grid.tiles_s));
  put<uint32_t>(header, 60, static_cast<uint32_t>(grid.tiles_t));
  put<uint64_t>(header, 64, index_offset);
  put<uint64_t>(header, 72, index.size());
  put<uint64_t>(header, 80, hash64(index.data(), index.size()));
  put<uint64_t>(header, 120, hash64(header.data(), 120));
  return header;
}

struct ZstdDeleter {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

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
      (zstd_level < kMinZstdLevel || zstd_level == 0 || zstd_level > ZSTD_maxCLevel())) {
    if (why)
      *why = "zstd level must be in [" + std::to_string(kMinZstdLevel) + ", -1] or [1, " +
             std::to_string(ZSTD_maxCLevel()) + "]";
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------------------------
// ObsTile

size_t ObsTile::index(int s, int t, int view) const {
  VDRIG_CHECK(contains(s, t), "texel outside the tile");
  VDRIG_CHECK(view >= 0 && view < views_, "view index out of range");
  return (static_cast<size_t>(t - t0_) * width_ + (s - s0_)) * views_ + view;
}

TexelObservations ObsTile::texel(int s, int t, const std::vector<int>& held_out) const {
  TexelObservations out;
  if (views_ == 0) return out;
  const size_t base = index(s, t, 0);
  for (int v = 0; v < views_; ++v) {
    const size_t i = base + v;
    if (flags_[i] != kObsValid) continue;
    if (!held_out.empty() && std::binary_search(held_out.begin(), held_out.end(), v)) continue;
    out.direction.emplace_back(direction_[3 * i], direction_[3 * i + 1], direction_[3 * i + 2]);
    out.radiance.emplace_back(radiance_[3 * i], radiance_[3 * i + 1], radiance_[3 * i + 2]);
    out.view.push_back(v);
  }
  return out;
}

uint8_t ObsTile::observation(int s, int t, int view, Eigen::Vector3f* rgb, Eigen::Vector3f* dir) const {
  const size_t i = index(s, t, view);
  *rgb = Eigen::Vector3f(radiance_[3 * i], radiance_[3 * i + 1], radiance_[3 * i + 2]);
  *dir = Eigen::Vector3f(direction_[3 * i], direction_[3 * i + 1], direction_[3 * i + 2]);
  return flags_[i];
}

// ---------------------------------------------------------------------------------------------------------------
// Writer

struct ObsMapWriter::Impl {
  fs::path path, tmp_path, spill_path;
  ObservationMapSpec spec;
  int views = 0;
  ObsFileOptions opt;
  TileGrid grid;
  Fd out, spill;
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
  std::unique_ptr<ZSTD_CCtx, ZstdDeleter> cctx{ZSTD_createCCtx()};
  std::unique_ptr<ZSTD_DCtx, ZstdDeleter> dctx{ZSTD_createDCtx()};

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
        z.resize(ZSTD_compressBound(raw.size()));
        const size_t zn = ZSTD_compressCCtx(cctx.get(), z.data(), z.size(), raw.data(), raw.size(),
                                            std::min(kSpillZstdLevel, opt.zstd_level));
        VDRIG_CHECK(!ZSTD_isError(zn), std::string("zstd: ") + ZSTD_getErrorName(zn));
        z.resize(zn);
        stored = &z;
      }
      chunks[static_cast<size_t>(view) * grid.count() + k] = {spill_end + block.size(), stored->size()};
      block.insert(block.end(), stored->begin(), stored->end());
    }
    VDRIG_TRY(write_at(spill.get(), spill_path, block.data(), block.size(), spill_end, opt));
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
    const size_t got = ZSTD_decompressDCtx(dctx.get(), raw.data(), n, z.data(), z.size());
    if (ZSTD_isError(got) || got != n)
      return make_error(ErrorCode::kIo, "spill file " + spill_path.string() + " read back damaged");
    return Status::ok();
  }

  Status finish() {
    if (finished) return make_error(ErrorCode::kInvalidArgument, "observation-map writer already finished");
    for (int v = 0; v < views; ++v)
      if (!added[v]) return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(v) + " was never added");
    std::vector<char> header(kHeaderBytes, 0);
    VDRIG_TRY(write_at(out.get(), tmp_path, header.data(), header.size(), 0, opt));
    uint64_t offset = kHeaderBytes;
    std::vector<char> index(kIndexEntryBytes * grid.count(), 0);
    std::vector<char> raw, z, payload;
    std::vector<float> trgb, tdir;
    std::vector<uint8_t> tflags;
    if (opt.compression == ObsCompression::kZstd) {
      ZSTD_CCtx_reset(cctx.get(), ZSTD_reset_session_and_parameters);
      ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, opt.zstd_level);
      ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_contentSizeFlag, 1);
      ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_checksumFlag, 1);
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
        z.resize(ZSTD_compressBound(payload.size()));
        const size_t zn = ZSTD_compress2(cctx.get(), z.data(), z.size(), payload.data(), payload.size());
        VDRIG_CHECK(!ZSTD_isError(zn), std::string("zstd: ") + ZSTD_getErrorName(zn));
        z.resize(zn);
        stored = &z;
      }
      VDRIG_TRY(write_at(out.get(), tmp_path, stored->data(), stored->size(), offset, opt));
      put<uint64_t>(index, kIndexEntryBytes * k, offset);
      put<uint64_t>(index, kIndexEntryBytes * k + 8, stored->size());
      put<uint64_t>(index, kIndexEntryBytes * k + 16, hash64(stored->data(), stored->size()));
      offset += stored->size();
    }
    VDRIG_TRY(write_at(out.get(), tmp_path, index.data(), index.size(), offset, opt));

    header = make_header(partial() ? kPartMagic : kMagic, spec, views, grid, opt.compression, offset, index);
    if (partial()) {
      put<uint32_t>(header, 88, static_cast<uint32_t>(opt.first_tile_row));
      put<uint32_t>(header, 92, static_cast<uint32_t>(opt.end_tile_row));
      put<uint64_t>(header, 120, hash64(header.data(), 120));
    }
    VDRIG_TRY(write_at(out.get(), tmp_path, header.data(), header.size(), 0, opt));

    if (::fsync(out.get()) != 0) return io_error("syncing", tmp_path, errno);
    out.reset();
    spill.reset();
    VDRIG_TRY(check_replaceable(path));
    if (::rename(tmp_path.c_str(), path.c_str()) != 0) return io_error("renaming into", path, errno);
    finished = true;
    // The rename is durable once the folder is synced; failing that is not worth failing the build for.
    (void)fsync_path(path.parent_path().empty() ? fs::path(".") : path.parent_path(), true);
    log::get("fitting")->info("observation map {} written: {}x{} texels x {} views, {} tiles, {:.1f} MB", path.string(),
                              spec.texels_s, spec.texels_t, views, grid.count(), (offset + index.size()) / 1e6);
    return Status::ok();
  }
};

namespace {

/// The process's umask, read without changing it (umask(2) would race with other threads creating files).
mode_t process_umask() {
  std::FILE* f = std::fopen("/proc/self/status", "re");
  unsigned mask = 022;
  if (f) {
    char line[256];
    while (std::fgets(line, sizeof line, f))
      if (std::sscanf(line, "Umask: %o", &mask) == 1) break;
    std::fclose(f);
  }
  return static_cast<mode_t>(mask);
}

}  // namespace

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

  const fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::string tmpl = (dir / (path.filename().string() + ".tmp-XXXXXX")).string();
  const int fd = ::mkstemp(tmpl.data());
  if (fd < 0) return io_error("creating a temporary file in", dir, errno);
  impl->out = Fd(fd);
  // mkstemp creates 0600; the finished file gets the mode of vdrig's other outputs (0666 less the umask).
  if (::fchmod(fd, 0666 & ~process_umask()) != 0) return io_error("setting the mode of", tmpl, errno);
  impl->tmp_path = tmpl;
  // The spill file is unlinked at once: the kernel frees it when the writer closes it or the process dies.
  const fs::path spill_dir = options.spill_dir.empty() ? dir : options.spill_dir;
  std::string stmpl = (spill_dir / ".vdrig-obsmap-spill-XXXXXX").string();
  const int sfd = ::mkstemp(stmpl.data());
  if (sfd < 0) return io_error("creating a spill file in", spill_dir, errno);
  impl->spill = Fd(sfd);
  impl->spill_path = stmpl;
  ::unlink(stmpl.c_str());
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

uint64_t obsfile_hash64(const void* data, size_t n) { return hash64(data, n); }

Status write_obsmap_file(const ObservationMap& map, const fs::path& path, const ObsFileOptions& options) {
  auto w = ObsMapWriter::create(path, map.spec(), map.views(), options);
  if (!w) return w.error();
  for (int v = 0; v < map.views(); ++v) VDRIG_TRY(w->add_view(v, map));
  return w->finish();
}

// ---------------------------------------------------------------------------------------------------------------
// Reader

struct ObsMapReader::Impl {
  fs::path path;
  Fd fd;
  ObsFileHeader header;
  TileGrid grid;
  struct Entry {
    uint64_t offset = 0, bytes = 0, hash = 0;
  };
  std::vector<Entry> index;

  Error corrupt(const std::string& why) const { return make_error(ErrorCode::kCorrupt, path.string() + ": " + why); }
};

Result<ObsMapReader> ObsMapReader::open(const fs::path& path) {
  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  m.path = path;
  m.fd = Fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (m.fd.get() < 0) {
    const int err = errno;
    return make_error(err == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo,
                      "opening " + path.string() + ": " + std::strerror(err));
  }
  struct stat st {};
  if (::fstat(m.fd.get(), &st) != 0) return io_error("stat of", path, errno);
  const uint64_t file_bytes = static_cast<uint64_t>(st.st_size);
  if (file_bytes < kHeaderBytes)
    return m.corrupt("truncated: " + std::to_string(file_bytes) + " bytes, the header alone is " +
                     std::to_string(kHeaderBytes));
  std::vector<char> h(kHeaderBytes);
  VDRIG_TRY(read_at(m.fd.get(), path, h.data(), h.size(), 0));
  if (std::memcmp(h.data(), kMagic, 8) != 0) return m.corrupt("not an observation-map file (magic is not VDRIGOBS)");
  const uint32_t version = get<uint32_t>(h, 8);
  if (version != kObsFileVersion)
    return make_error(ErrorCode::kUnsupported, path.string() + ": observation-map format version " +
                                                   std::to_string(version) + ", this build reads version " +
                                                   std::to_string(kObsFileVersion));
  if (!checksum_matches(get<uint64_t>(h, 120), h.data(), 120))
    return m.corrupt("header checksum mismatch (damaged header)");
  ObsFileHeader& hd = m.header;
  hd.version = version;
  hd.spec.texels_s = get<int32_t>(h, 16);
  hd.spec.texels_t = get<int32_t>(h, 20);
  hd.views = get<int32_t>(h, 24);
  hd.tile_size = get<int32_t>(h, 28);
  hd.spec.width_mm = get<double>(h, 32);
  hd.spec.height_mm = get<double>(h, 40);
  const uint32_t compression = get<uint32_t>(h, 48);
  std::string why;
  if (get<uint32_t>(h, 12) != kHeaderBytes || get<uint32_t>(h, 52) != kRecordLayout)
    return m.corrupt("unknown header size or record layout");
  if (!hd.spec.is_valid(&why) || hd.spec.texels_s > kMaxTexelsPerSide || hd.spec.texels_t > kMaxTexelsPerSide)
    return m.corrupt("bad map size in header (" + std::to_string(hd.spec.texels_s) + "x" +
                     std::to_string(hd.spec.texels_t) + ")");
  if (hd.views < 0 || hd.views > kMaxViews) return m.corrupt("bad view count " + std::to_string(hd.views));
  if (hd.tile_size < 1 || hd.tile_size > kMaxTileSize)
    return m.corrupt("bad tile size " + std::to_string(hd.tile_size));
  if (compression > 1) return m.corrupt("unknown compression " + std::to_string(compression));
  hd.compression = static_cast<ObsCompression>(compression);
  // Sizes from the header are checked before anything is allocated from them: the tile count against the file (its
  // index must fit; this also keeps the count within int), the largest tile against what a read may allocate.
  const uint64_t tile_count = static_cast<uint64_t>(ceil_div(hd.spec.texels_s, hd.tile_size)) *
                              static_cast<uint64_t>(ceil_div(hd.spec.texels_t, hd.tile_size));
  if (tile_count * kIndexEntryBytes > file_bytes)
    return m.corrupt("truncated: " + std::to_string(tile_count) + " tiles need a " +
                     std::to_string(tile_count * kIndexEntryBytes) + "-byte index, the file has " +
                     std::to_string(file_bytes) + " bytes");
  if (const std::string why_big = tile_too_large(hd.tile_size, hd.spec.texels_s, hd.spec.texels_t, hd.views);
      !why_big.empty())
    return m.corrupt(why_big);
  m.grid = TileGrid(hd.spec.texels_s, hd.spec.texels_t, hd.tile_size);
  hd.tiles_s = m.grid.tiles_s;
  hd.tiles_t = m.grid.tiles_t;
  if (get<uint32_t>(h, 56) != static_cast<uint32_t>(hd.tiles_s) ||
      get<uint32_t>(h, 60) != static_cast<uint32_t>(hd.tiles_t))
    return m.corrupt("tile counts disagree with map and tile size");
  hd.file_bytes = file_bytes;

  const uint64_t index_offset = get<uint64_t>(h, 64), index_bytes = get<uint64_t>(h, 72);
  if (index_bytes != kIndexEntryBytes * static_cast<uint64_t>(m.grid.count()))
    return m.corrupt("index size disagrees with the tile count");
  if (index_offset < kHeaderBytes || index_offset > file_bytes || index_bytes > file_bytes - index_offset)
    return m.corrupt("truncated: the tile index ends at byte " + std::to_string(index_offset + index_bytes) +
                     ", the file has " + std::to_string(file_bytes));
  std::vector<char> idx(index_bytes);
  VDRIG_TRY(read_at(m.fd.get(), path, idx.data(), idx.size(), index_offset));
  if (!checksum_matches(get<uint64_t>(h, 80), idx.data(), idx.size())) return m.corrupt("tile index checksum mismatch");
  m.header.index_checksum = get<uint64_t>(h, 80);
  m.index.resize(m.grid.count());
  for (int k = 0; k < m.grid.count(); ++k) {
    Impl::Entry& e = m.index[k];
    e.offset = get<uint64_t>(idx, kIndexEntryBytes * k);
    e.bytes = get<uint64_t>(idx, kIndexEntryBytes * k + 8);
    e.hash = get<uint64_t>(idx, kIndexEntryBytes * k + 16);
    const uint64_t raw = raw_bytes(m.grid.texels(k) * static_cast<uint64_t>(hd.views));
    if (e.offset < kHeaderBytes || e.offset > index_offset || e.bytes > index_offset - e.offset)
      return m.corrupt("tile " + std::to_string(k) + " lies outside the data area");
    if (hd.compression == ObsCompression::kNone && e.bytes != raw)
      return m.corrupt("tile " + std::to_string(k) + " has the wrong size");
    hd.stored_tile_bytes += e.bytes;
    hd.raw_tile_bytes += raw;
  }
  return ObsMapReader(std::move(impl));
}

ObsMapReader::ObsMapReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ObsMapReader::ObsMapReader(ObsMapReader&&) noexcept = default;
ObsMapReader& ObsMapReader::operator=(ObsMapReader&&) noexcept = default;
ObsMapReader::~ObsMapReader() = default;
const ObsFileHeader& ObsMapReader::header() const { return impl_->header; }

Result<ObsTile> ObsMapReader::read_tile(int tile_s, int tile_t) const {
  const Impl& m = *impl_;
  if (tile_s < 0 || tile_s >= m.grid.tiles_s || tile_t < 0 || tile_t >= m.grid.tiles_t)
    return make_error(ErrorCode::kInvalidArgument, "tile (" + std::to_string(tile_s) + ", " + std::to_string(tile_t) +
                                                       ") out of range: " + m.path.string() + " has " +
                                                       std::to_string(m.grid.tiles_s) + " x " +
                                                       std::to_string(m.grid.tiles_t) + " tiles");
  const int k = tile_t * m.grid.tiles_s + tile_s;
  const Impl::Entry& e = m.index[k];
  const size_t V = static_cast<size_t>(m.header.views), nt = m.grid.texels(k), n = nt * V;
  std::vector<char> stored(e.bytes);
  VDRIG_TRY(read_at(m.fd.get(), m.path, stored.data(), stored.size(), e.offset));
  const std::string name = "tile (" + std::to_string(tile_s) + ", " + std::to_string(tile_t) + ")";
  if (!checksum_matches(e.hash, stored.data(), stored.size()))
    return m.corrupt(name + " checksum mismatch (damaged data)");
  std::vector<char> raw;
  if (m.header.compression == ObsCompression::kZstd) {
    const unsigned long long content = ZSTD_getFrameContentSize(stored.data(), stored.size());
    if (content != raw_bytes(n)) return m.corrupt(name + " does not decompress to its expected size");
    raw.resize(raw_bytes(n));
    const size_t got = ZSTD_decompress(raw.data(), raw.size(), stored.data(), stored.size());
    if (ZSTD_isError(got) || got != raw.size())
      return m.corrupt(name + " fails to decompress" +
                       (ZSTD_isError(got) ? std::string(": ") + ZSTD_getErrorName(got) : std::string()));
  } else {
    raw = std::move(stored);
  }
  ObsTile tile;
  tile.s0_ = tile_s * m.grid.tile;
  tile.t0_ = tile_t * m.grid.tile;
  tile.width_ = m.grid.width(tile_s);
  tile.height_ = m.grid.height(tile_t);
  tile.views_ = m.header.views;
  tile.radiance_.resize(3 * n);
  tile.direction_.resize(3 * n);
  tile.flags_.resize(n);
  if (n > 0) {  // a map of 0 views has empty tiles (and null data pointers, which memcpy must not get)
    std::memcpy(tile.radiance_.data(), raw.data(), 12 * n);
    std::memcpy(tile.direction_.data(), raw.data() + 12 * n, 12 * n);
    std::memcpy(tile.flags_.data(), raw.data() + 24 * n, n);
  }
  return tile;
}

Result<ObsTile> ObsMapReader::read_tile_of_texel(int s, int t) const {
  const ObservationMapSpec& spec = impl_->header.spec;
  if (s < 0 || s >= spec.texels_s || t < 0 || t >= spec.texels_t)
    return make_error(ErrorCode::kInvalidArgument, "texel (" + std::to_string(s) + ", " + std::to_string(t) +
                                                       ") out of range: the map is " + std::to_string(spec.texels_s) +
                                                       " x " + std::to_string(spec.texels_t));
  return read_tile(s / impl_->grid.tile, t / impl_->grid.tile);
}

Result<ObservationMap> ObsMapReader::read_all() const {
  const Impl& m = *impl_;
  ObservationMap map(m.header.spec, m.header.views);
  for (int tt = 0; tt < m.grid.tiles_t; ++tt)
    for (int ts = 0; ts < m.grid.tiles_s; ++ts) {
      auto tile = read_tile(ts, tt);
      if (!tile) return tile.error();
      for (int t = tile->t0(); t < tile->t0() + tile->height(); ++t)
        for (int s = tile->s0(); s < tile->s0() + tile->width(); ++s)
          for (int v = 0; v < m.header.views; ++v) {
            Eigen::Vector3f rgb, dir;
            const uint8_t f = tile->observation(s, t, v, &rgb, &dir);
            map.set(s, t, v, rgb, dir, f);
          }
    }
  return map;
}

}  // namespace vdrig::fitting

namespace vdrig::fitting {

Status assemble_obsmap_parts(const std::vector<fs::path>& parts, const fs::path& path) {
  struct Part {
    fs::path path;
    Fd fd;
    std::vector<char> header, index;
    uint32_t first = 0, end = 0;
  };
  if (parts.empty()) return make_error(ErrorCode::kInvalidArgument, "no observation-map parts to assemble");
  std::vector<Part> in(parts.size());
  for (size_t i = 0; i < parts.size(); ++i) {
    Part& p = in[i];
    p.path = parts[i];
    p.fd = Fd(::open(p.path.c_str(), O_RDONLY | O_CLOEXEC));
    if (p.fd.get() < 0) return io_error("opening", p.path, errno);
    p.header.resize(kHeaderBytes);
    VDRIG_TRY(read_at(p.fd.get(), p.path, p.header.data(), kHeaderBytes, 0));
    auto corrupt = [&](const std::string& why) {
      return make_error(ErrorCode::kCorrupt, p.path.string() + ": " + why);
    };
    if (std::memcmp(p.header.data(), kPartMagic, 8) != 0) return corrupt("not an observation-map part");
    if (!checksum_matches(get<uint64_t>(p.header, 120), p.header.data(), 120)) return corrupt("header checksum");
    // Every field but the rows, the index's place and the checksums must be the first part's.
    if (i > 0 && (std::memcmp(p.header.data(), in[0].header.data(), 64) != 0))
      return corrupt("a part of another observation map than " + in[0].path.string());
    p.first = get<uint32_t>(p.header, 88);
    p.end = get<uint32_t>(p.header, 92);
    p.index.resize(get<uint64_t>(p.header, 72));
    VDRIG_TRY(read_at(p.fd.get(), p.path, p.index.data(), p.index.size(), get<uint64_t>(p.header, 64)));
    if (!checksum_matches(get<uint64_t>(p.header, 80), p.index.data(), p.index.size()))
      return corrupt("index checksum");
  }
  const std::vector<char>& h0 = in[0].header;
  const ObservationMapSpec spec{get<int32_t>(h0, 16), get<int32_t>(h0, 20), get<double>(h0, 32), get<double>(h0, 40)};
  const int views = get<int32_t>(h0, 24);
  const TileGrid grid(spec.texels_s, spec.texels_t, get<int32_t>(h0, 28));
  const auto compression = static_cast<ObsCompression>(get<uint32_t>(h0, 48));
  if (in[0].index.size() != kIndexEntryBytes * static_cast<size_t>(grid.count()))
    return make_error(ErrorCode::kCorrupt, in[0].path.string() + ": index size disagrees with the tile count");
  // Which part holds each tile row: exactly one.
  std::vector<int> owner(static_cast<size_t>(grid.tiles_t), -1);
  for (size_t i = 0; i < in.size(); ++i)
    for (uint32_t r = in[i].first; r < in[i].end && r < owner.size(); ++r) {
      if (owner[r] >= 0)
        return make_error(ErrorCode::kInvalidArgument, "tile row " + std::to_string(r) + " is in two parts");
      owner[r] = static_cast<int>(i);
    }
  for (size_t r = 0; r < owner.size(); ++r)
    if (owner[r] < 0) return make_error(ErrorCode::kInvalidArgument, "no part holds tile row " + std::to_string(r));

  const fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::string tmpl = (dir / (path.filename().string() + ".tmp-XXXXXX")).string();
  Fd out(::mkstemp(tmpl.data()));
  if (out.get() < 0) return io_error("creating a temporary file in", dir, errno);
  const fs::path tmp = tmpl;
  struct Cleanup {
    const fs::path& p;
    bool keep = false;
    ~Cleanup() {
      if (!keep) ::unlink(p.c_str());
    }
  } cleanup{tmp};
  if (::fchmod(out.get(), 0666 & ~process_umask()) != 0) return io_error("setting the mode of", tmp, errno);
  const ObsFileOptions no_hooks;
  uint64_t offset = kHeaderBytes;
  std::vector<char> index(kIndexEntryBytes * static_cast<size_t>(grid.count()), 0), stored;
  for (int k = 0; k < grid.count(); ++k) {
    const Part& p = in[static_cast<size_t>(owner[static_cast<size_t>(k / grid.tiles_s)])];
    const uint64_t at = get<uint64_t>(p.index, kIndexEntryBytes * k),
                   n = get<uint64_t>(p.index, kIndexEntryBytes * k + 8);
    const uint64_t hash = get<uint64_t>(p.index, kIndexEntryBytes * k + 16);
    if (n > (uint64_t{1} << 32))
      return make_error(ErrorCode::kCorrupt, p.path.string() + ": tile " + std::to_string(k) + " too large");
    stored.resize(n);
    VDRIG_TRY(read_at(p.fd.get(), p.path, stored.data(), n, at));
    if (!checksum_matches(hash, stored.data(), n))
      return make_error(ErrorCode::kCorrupt, p.path.string() + ": tile " + std::to_string(k) + " checksum mismatch");
    VDRIG_TRY(write_at(out.get(), tmp, stored.data(), n, offset, no_hooks));
    put<uint64_t>(index, kIndexEntryBytes * k, offset);
    put<uint64_t>(index, kIndexEntryBytes * k + 8, n);
    put<uint64_t>(index, kIndexEntryBytes * k + 16, hash);
    offset += n;
  }
  VDRIG_TRY(write_at(out.get(), tmp, index.data(), index.size(), offset, no_hooks));
  const std::vector<char> header = make_header(kMagic, spec, views, grid, compression, offset, index);
  VDRIG_TRY(write_at(out.get(), tmp, header.data(), header.size(), 0, no_hooks));
  if (::fsync(out.get()) != 0) return io_error("syncing", tmp, errno);
  out.reset();
  VDRIG_TRY(check_replaceable(path));
  if (::rename(tmp.c_str(), path.c_str()) != 0) return io_error("renaming into", path, errno);
  cleanup.keep = true;
  (void)fsync_path(dir, true);
  log::get("fitting")->info("observation map {} assembled from {} parts: {:.1f} MB", path.string(), parts.size(),
                            (offset + index.size()) / 1e6);
  return Status::ok();
}

}  // namespace vdrig::fitting

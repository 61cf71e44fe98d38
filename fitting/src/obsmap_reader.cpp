// ObsMapReader and ObsTile: an observation-map file opened, checked (header, index) and read a tile at a time
// (docs/obsmap.md, "Reading").
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "obsmap_checksum.hpp"
#include "obsmap_format.hpp"
#include "obsmap_zstd.hpp"
#include "positional_file_io.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::fitting {
namespace fs = std::filesystem;
using namespace obsmap_format;

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
// Reader

struct ObsMapReader::Impl {
  fs::path path;
  UniqueFd fd;
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
  auto fd = open_for_reading(path);
  if (!fd) return fd.error();
  m.fd = std::move(fd.value());
  struct stat st {};
  if (::fstat(m.fd.get(), &st) != 0) return error_from_errno(errno, "stat of " + path.string());
  const uint64_t file_bytes = static_cast<uint64_t>(st.st_size);
  if (file_bytes < kHeaderBytes)
    return m.corrupt("truncated: " + std::to_string(file_bytes) + " bytes, the header alone is " +
                     std::to_string(kHeaderBytes));
  std::vector<char> h(kHeaderBytes);
  VDRIG_TRY(read_at(m.fd.get(), path, h.data(), h.size(), 0));
  if (std::memcmp(h.data(), kMagic, 8) != 0) return m.corrupt("not an observation-map file (magic is not VDRIGOBS)");
  const uint32_t version = get<uint32_t>(h, kAtVersion);
  if (version < kObsFileOldestVersion || version > kObsFileVersion)
    return make_error(ErrorCode::kUnsupported, path.string() + ": observation-map format version " +
                                                   std::to_string(version) + ", this build reads versions " +
                                                   std::to_string(kObsFileOldestVersion) + " to " +
                                                   std::to_string(kObsFileVersion));
  if (!obsmap_checksum_matches(get<uint64_t>(h, kAtHeaderChecksum), h.data(), kAtHeaderChecksum))
    return m.corrupt("header checksum mismatch (damaged header)");
  ObsFileHeader& hd = m.header;
  hd.version = version;
  hd.spec.texels_s = get<int32_t>(h, kAtTexelsS);
  hd.spec.texels_t = get<int32_t>(h, kAtTexelsT);
  hd.views = get<int32_t>(h, kAtViews);
  hd.tile_size = get<int32_t>(h, kAtTileSize);
  hd.spec.width_mm = get<double>(h, kAtWidthMm);
  hd.spec.height_mm = get<double>(h, kAtHeightMm);
  const uint32_t compression = get<uint32_t>(h, kAtCompression);
  std::string why;
  if (get<uint32_t>(h, kAtHeaderBytes) != kHeaderBytes || get<uint32_t>(h, kAtRecordLayout) != kRecordLayout)
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
  if (get<uint32_t>(h, kAtTilesS) != static_cast<uint32_t>(hd.tiles_s) ||
      get<uint32_t>(h, kAtTilesT) != static_cast<uint32_t>(hd.tiles_t))
    return m.corrupt("tile counts disagree with map and tile size");
  hd.file_bytes = file_bytes;

  const uint64_t index_offset = get<uint64_t>(h, kAtIndexOffset), index_bytes = get<uint64_t>(h, kAtIndexBytes);
  if (index_bytes != kIndexEntryBytes * static_cast<uint64_t>(m.grid.count()))
    return m.corrupt("index size disagrees with the tile count");
  if (index_offset < kHeaderBytes || index_offset > file_bytes || index_bytes > file_bytes - index_offset)
    return m.corrupt("truncated: the tile index ends at byte " + std::to_string(index_offset + index_bytes) +
                     ", the file has " + std::to_string(file_bytes));
  std::vector<char> idx(index_bytes);
  VDRIG_TRY(read_at(m.fd.get(), path, idx.data(), idx.size(), index_offset));
  if (!obsmap_checksum_matches(get<uint64_t>(h, kAtIndexChecksum), idx.data(), idx.size()))
    return m.corrupt("tile index checksum mismatch");
  m.header.index_checksum = get<uint64_t>(h, kAtIndexChecksum);
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
  if (!obsmap_checksum_matches(e.hash, stored.data(), stored.size()))
    return m.corrupt(name + " checksum mismatch (damaged data)");
  std::vector<char> raw;
  if (m.header.compression == ObsCompression::kZstd) {
    if (const std::string why = zstd_decompress_exact(stored, raw_bytes(n), raw); !why.empty())
      return m.corrupt(name + " " + why);
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

// The on-disk layout of observation-map files and parts (docs/obsmap.md): header fields, tile geometry, the raw
// tile record and the limits a reader enforces. Shared by the writer (obsmap_writer.cpp), the reader
// (obsmap_reader.cpp) and the assembly of MPI parts (obsmap_parts.cpp).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::fitting::obsmap_format {

// The format is little-endian (docs/obsmap.md); this implementation writes its native layout.
static_assert(std::endian::native == std::endian::little, "obsmap files are little-endian; add byte swapping here");

inline constexpr char kMagic[8] = {'V', 'D', 'R', 'I', 'G', 'O', 'B', 'S'};
inline constexpr char kPartMagic[8] = {'V', 'D', 'R', 'I', 'G', 'O', 'B', 'P'};
inline constexpr size_t kHeaderBytes = 128;
inline constexpr size_t kIndexEntryBytes = 24;
inline constexpr uint32_t kRecordLayout = 1;  // per tile: radiance f32x3, direction f32x3, flag u8 (planes, docs)
inline constexpr size_t kBytesPerObservation = 25;
inline constexpr int kMaxTileSize = 4096;
inline constexpr int kMaxTexelsPerSide = 1 << 20;
inline constexpr int kMaxViews = 1 << 20;
/// A tile is read whole (stored, raw, then its arrays): the reader refuses tiles larger than this uncompressed
/// (e.g. 32 x 32 texels x 20,000 views, or 128 x 128 x 1,300), so a header's dimensions cannot make it allocate
/// gigabytes; the writer refuses to write what the reader would refuse.
inline constexpr uint64_t kMaxTileRawBytes = uint64_t{512} << 20;

// Header field offsets (bytes).
inline constexpr size_t kAtVersion = 8, kAtHeaderBytes = 12, kAtTexelsS = 16, kAtTexelsT = 20, kAtViews = 24,
                        kAtTileSize = 28, kAtWidthMm = 32, kAtHeightMm = 40, kAtCompression = 48, kAtRecordLayout = 52,
                        kAtTilesS = 56, kAtTilesT = 60, kAtIndexOffset = 64, kAtIndexBytes = 72, kAtIndexChecksum = 80,
                        kAtPartFirstRow = 88, kAtPartEndRow = 92, kAtHeaderChecksum = 120;

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

inline int ceil_div(int a, int b) { return (a + b - 1) / b; }

/// Geometry of the tiles of a map.
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
inline size_t raw_bytes(size_t n) { return n * kBytesPerObservation; }

/// Why a map's largest tile is more than a reader may allocate (kMaxTileRawBytes), or "" when it is not.
std::string tile_too_large(int tile_size, int texels_s, int texels_t, int views);

/// Packs n observations into the raw tile record (resizing `out`).
void pack(std::vector<char>& out, const float* rgb, const float* dir, const uint8_t* flags, size_t n);

/// The 128-byte header of a file (magic kMagic) or part (kPartMagic; its tile rows are added by the caller, who
/// then recomputes the header checksum).
std::vector<char> make_header(const char* magic, const ObservationMapSpec& spec, int views, const TileGrid& grid,
                              ObsCompression compression, uint64_t index_offset, const std::vector<char>& index);

}  // namespace vdrig::fitting::obsmap_format

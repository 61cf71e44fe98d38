#include "obsmap_format.hpp"

#include "obsmap_checksum.hpp"

namespace vdrig::fitting::obsmap_format {

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

std::vector<char> make_header(const char* magic, const ObservationMapSpec& spec, int views, const TileGrid& grid,
                              ObsCompression compression, uint64_t index_offset, const std::vector<char>& index) {
  std::vector<char> header(kHeaderBytes, 0);
  std::memcpy(header.data(), magic, 8);
  put<uint32_t>(header, kAtVersion, kObsFileVersion);
  put<uint32_t>(header, kAtHeaderBytes, kHeaderBytes);
  put<int32_t>(header, kAtTexelsS, spec.texels_s);
  put<int32_t>(header, kAtTexelsT, spec.texels_t);
  put<int32_t>(header, kAtViews, views);
  put<int32_t>(header, kAtTileSize, grid.tile);
  put<double>(header, kAtWidthMm, spec.width_mm);
  put<double>(header, kAtHeightMm, spec.height_mm);
  put<uint32_t>(header, kAtCompression, static_cast<uint32_t>(compression));
  put<uint32_t>(header, kAtRecordLayout, kRecordLayout);
  put<uint32_t>(header, kAtTilesS, static_cast<uint32_t>(grid.tiles_s));
  put<uint32_t>(header, kAtTilesT, static_cast<uint32_t>(grid.tiles_t));
  put<uint64_t>(header, kAtIndexOffset, index_offset);
  put<uint64_t>(header, kAtIndexBytes, index.size());
  put<uint64_t>(header, kAtIndexChecksum, obsmap_hash64(index.data(), index.size()));
  put<uint64_t>(header, kAtHeaderChecksum, obsmap_hash64(header.data(), kAtHeaderChecksum));
  return header;
}

}  // namespace vdrig::fitting::obsmap_format

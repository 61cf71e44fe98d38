// zstd compression of observation-map tiles (docs/obsmap.md, "Compression"): the writer's two uses (the spill, fast
// and read once; the file's tiles, at the chosen level with content size and checksum in each frame) and the
// reader's checked decompression. Keeps <zstd.h> out of the writer and reader.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace vdrig::fitting {

/// zstd's highest compression level (ZSTD_maxCLevel).
int zstd_max_level();

/// A compression context reused across tiles. Not thread-safe (one per writer).
class ZstdTileCompressor {
 public:
  ZstdTileCompressor();
  ~ZstdTileCompressor();
  ZstdTileCompressor(const ZstdTileCompressor&) = delete;
  ZstdTileCompressor& operator=(const ZstdTileCompressor&) = delete;

  /// One frame of `raw` at `level`, with zstd's default frame parameters (the spill).
  void compress(const std::vector<char>& raw, int level, std::vector<char>& out);
  /// Sets the parameters of compress_file_tile: `level`, the content size and a checksum in every frame.
  void set_file_tile_parameters(int level);
  /// One frame of `raw` with the parameters set by set_file_tile_parameters (a tile of the file).
  void compress_file_tile(const std::vector<char>& raw, std::vector<char>& out);

 private:
  struct Context;
  std::unique_ptr<Context> context_;
};

/// Decompression with a reused context. Not thread-safe.
class ZstdTileDecompressor {
 public:
  ZstdTileDecompressor();
  ~ZstdTileDecompressor();
  ZstdTileDecompressor(const ZstdTileDecompressor&) = delete;
  ZstdTileDecompressor& operator=(const ZstdTileDecompressor&) = delete;

  /// Decompresses `stored` into exactly raw_size bytes of `raw`; false when it fails or yields another size.
  bool decompress(const std::vector<char>& stored, size_t raw_size, std::vector<char>& raw);

 private:
  struct Context;
  std::unique_ptr<Context> context_;
};

/// Decompresses one frame that must declare (in its header) and yield exactly raw_size bytes, without a reused
/// context (the reader's tiles, read from several threads). "" on success, else why not ("does not decompress to
/// its expected size", "fails to decompress: <zstd's reason>").
std::string zstd_decompress_exact(const std::vector<char>& stored, size_t raw_size, std::vector<char>& raw);

}  // namespace vdrig::fitting

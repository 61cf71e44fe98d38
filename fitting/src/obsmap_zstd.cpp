#include "obsmap_zstd.hpp"

#include <zstd.h>

#include "vdrig/core/result.hpp"

namespace vdrig::fitting {

int zstd_max_level() { return ZSTD_maxCLevel(); }

struct ZstdTileCompressor::Context {
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  ~Context() { ZSTD_freeCCtx(cctx); }
};

ZstdTileCompressor::ZstdTileCompressor() : context_(std::make_unique<Context>()) {}
ZstdTileCompressor::~ZstdTileCompressor() = default;

void ZstdTileCompressor::compress(const std::vector<char>& raw, int level, std::vector<char>& out) {
  out.resize(ZSTD_compressBound(raw.size()));
  const size_t n = ZSTD_compressCCtx(context_->cctx, out.data(), out.size(), raw.data(), raw.size(), level);
  VDRIG_CHECK(!ZSTD_isError(n), std::string("zstd: ") + ZSTD_getErrorName(n));
  out.resize(n);
}

void ZstdTileCompressor::set_file_tile_parameters(int level) {
  ZSTD_CCtx_reset(context_->cctx, ZSTD_reset_session_and_parameters);
  ZSTD_CCtx_setParameter(context_->cctx, ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(context_->cctx, ZSTD_c_contentSizeFlag, 1);
  ZSTD_CCtx_setParameter(context_->cctx, ZSTD_c_checksumFlag, 1);
}

void ZstdTileCompressor::compress_file_tile(const std::vector<char>& raw, std::vector<char>& out) {
  out.resize(ZSTD_compressBound(raw.size()));
  const size_t n = ZSTD_compress2(context_->cctx, out.data(), out.size(), raw.data(), raw.size());
  VDRIG_CHECK(!ZSTD_isError(n), std::string("zstd: ") + ZSTD_getErrorName(n));
  out.resize(n);
}

struct ZstdTileDecompressor::Context {
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  ~Context() { ZSTD_freeDCtx(dctx); }
};

ZstdTileDecompressor::ZstdTileDecompressor() : context_(std::make_unique<Context>()) {}
ZstdTileDecompressor::~ZstdTileDecompressor() = default;

bool ZstdTileDecompressor::decompress(const std::vector<char>& stored, size_t raw_size, std::vector<char>& raw) {
  raw.resize(raw_size);
  const size_t got = ZSTD_decompressDCtx(context_->dctx, raw.data(), raw_size, stored.data(), stored.size());
  return !ZSTD_isError(got) && got == raw_size;
}

std::string zstd_decompress_exact(const std::vector<char>& stored, size_t raw_size, std::vector<char>& raw) {
  const unsigned long long content = ZSTD_getFrameContentSize(stored.data(), stored.size());
  if (content != raw_size) return "does not decompress to its expected size";
  raw.resize(raw_size);
  const size_t got = ZSTD_decompress(raw.data(), raw.size(), stored.data(), stored.size());
  if (ZSTD_isError(got) || got != raw.size())
    return std::string("fails to decompress") +
           (ZSTD_isError(got) ? std::string(": ") + ZSTD_getErrorName(got) : std::string());
  return "";
}

}  // namespace vdrig::fitting

#include "obsmap_checksum.hpp"

#include <cstring>

#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::fitting {

uint64_t obsmap_hash64(const void* data, size_t n) {
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

bool obsmap_checksum_matches(uint64_t stored, const void* data, size_t n) {
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
  (void)stored, (void)data, (void)n;
  return true;
#else
  return stored == obsmap_hash64(data, n);
#endif
}

uint64_t obsfile_hash64(const void* data, size_t n) { return obsmap_hash64(data, n); }

}  // namespace vdrig::fitting

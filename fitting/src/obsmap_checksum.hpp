// The observation-map format's checksum (docs/obsmap.md, "hash64"): one function for headers, indexes and tiles,
// public as fitting::obsfile_hash64 (obsmap_file.hpp) for the tile records of cluster/ and hand-made test files.
#pragma once

#include <cstddef>
#include <cstdint>

namespace vdrig::fitting {

/// 64-bit hash of a byte range (8 bytes at a time, murmur-style mixing): catches flipped bits and torn writes.
uint64_t obsmap_hash64(const void* data, size_t n);

/// Whether a stored checksum matches. Fuzzing builds skip the comparison: a mutated input could never pass it, and
/// the fuzzer would never reach the size checks and the decompressor behind it (docs/fuzzing.md).
bool obsmap_checksum_matches(uint64_t stored, const void* data, size_t n);

}  // namespace vdrig::fitting

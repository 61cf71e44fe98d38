// splitmix64 (Steele, Lea and Flood; the finaliser of Vigna's reference code): a tiny generator and bit mixer whose
// output is fixed by its definition, for seeds that must give the same result on every platform and standard library
// (std::uniform_real_distribution and std::hash are not the same across them).
#pragma once

#include <cstdint>

namespace vdrig {

/// The splitmix64 finaliser: every input bit reaches every output bit.
constexpr uint64_t splitmix64_finalise(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// The golden-ratio increment of the splitmix64 stream.
constexpr uint64_t kSplitMix64Increment = 0x9E3779B97F4A7C15ull;

/// The splitmix64 stream from `state`.
struct SplitMix64 {
  uint64_t state;
  uint64_t next() { return splitmix64_finalise(state += kSplitMix64Increment); }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

}  // namespace vdrig

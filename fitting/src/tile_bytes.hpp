// Little-endian packing of tile records (tiled_fit.hpp): native layout, as the observation-map files.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/tiled_fit.hpp"

namespace vdrig::fitting {

static_assert(std::endian::native == std::endian::little, "tile records are little-endian; add byte swapping here");

class BytesOut {
 public:
  explicit BytesOut(TileBytes& out) : out_(out) {}
  template <typename T>
  void put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const size_t at = out_.size();
    out_.resize(at + sizeof(T));
    std::memcpy(out_.data() + at, &v, sizeof(T));
  }
  void put_bytes(const void* data, size_t n) {
    const size_t at = out_.size();
    out_.resize(at + n);
    if (n) std::memcpy(out_.data() + at, data, n);
  }
  void put_string(const std::string& s) {
    put<uint32_t>(static_cast<uint32_t>(s.size()));
    put_bytes(s.data(), s.size());
  }

 private:
  TileBytes& out_;
};

/// Reads back what BytesOut wrote; any read past the end sets failed() (the record is then kCorrupt).
class BytesIn {
 public:
  BytesIn(const uint8_t* data, size_t n) : p_(data), n_(n) {}
  explicit BytesIn(const TileBytes& b) : BytesIn(b.data(), b.size()) {}
  template <typename T>
  T get() {
    T v{};
    get_bytes(&v, sizeof(T));
    return v;
  }
  void get_bytes(void* out, size_t n) {
    if (failed_ || n > n_ - at_) {
      failed_ = true;
      return;
    }
    if (n) std::memcpy(out, p_ + at_, n);
    at_ += n;
  }
  std::string get_string() {
    const uint32_t n = get<uint32_t>();
    if (failed_ || n > n_ - at_) {
      failed_ = true;
      return {};
    }
    std::string s(reinterpret_cast<const char*>(p_ + at_), n);
    at_ += n;
    return s;
  }
  /// Marks the record malformed (a count out of range).
  void fail() { failed_ = true; }
  bool failed() const { return failed_; }
  bool at_end() const { return at_ == n_; }
  /// kCorrupt naming `what` unless everything was read exactly.
  Status finish(const std::string& what) const {
    if (failed_ || !at_end()) return make_error(ErrorCode::kCorrupt, what + ": malformed tile record");
    return Status::ok();
  }

 private:
  const uint8_t* p_;
  size_t n_, at_ = 0;
  bool failed_ = false;
};

}  // namespace vdrig::fitting

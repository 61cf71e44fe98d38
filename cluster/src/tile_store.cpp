#include "vdrig/cluster/tile_store.hpp"

#include <fmt/format.h>

#include <cstring>
#include <fstream>
#include <iterator>

#include "vdrig/core/file_write.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::cluster {
namespace fs = std::filesystem;
namespace {

constexpr char kMagic[8] = {'V', 'D', 'R', 'I', 'G', 'T', 'I', 'L'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 48;

template <typename T>
void put(std::string& b, size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}
template <typename T>
T get(const std::string& b, size_t at) {
  T v;
  std::memcpy(&v, b.data() + at, sizeof v);
  return v;
}

}  // namespace

Result<TileStore> TileStore::open(const fs::path& root, const std::string& fingerprint, bool create_description) {
  TileStore store;
  store.root_ = root;
  store.hash_ = fitting::obsfile_hash64(fingerprint.data(), fingerprint.size());
  store.folder_ = root / fmt::format("{:016x}", store.hash_);
  std::error_code ec;
  fs::create_directories(store.folder_, ec);
  if (ec) return make_error(ErrorCode::kIo, "creating the tile folder " + store.folder_.string() + ": " + ec.message());
  if (create_description) {
    const fs::path description = store.folder_ / "fit.txt";
    std::ifstream in(description, std::ios::binary);
    const std::string old((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (old.empty()) {
      VDRIG_TRY(write_file_atomic(description, fingerprint + "\n"));
    } else if (old != fingerprint + "\n") {
      // Two fingerprints with one 64-bit hash: never mix their tiles.
      return make_error(ErrorCode::kCorrupt, description.string() + " describes another fit (hash collision?)");
    }
  }
  return store;
}

fs::path TileStore::record_path(int pass, int tile) const {
  return folder_ / fmt::format("p{}_{:06d}.rec", pass, tile);
}

Result<fitting::TileBytes> TileStore::read(int pass, int tile) const {
  const fs::path path = record_path(pass, tile);
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(ErrorCode::kNotFound, path.string() + ": no record");
  const std::string b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto bad = [&](const std::string& why) { return make_error(ErrorCode::kCorrupt, path.string() + ": " + why); };
  if (b.size() < kHeaderBytes || std::memcmp(b.data(), kMagic, 8) != 0) return bad("not a tile record");
  if (get<uint32_t>(b, 8) != kVersion) return bad("record version " + std::to_string(get<uint32_t>(b, 8)));
  if (get<uint32_t>(b, 12) != static_cast<uint32_t>(pass) || get<uint32_t>(b, 24) != static_cast<uint32_t>(tile))
    return bad("record of another tile or pass");
  if (get<uint64_t>(b, 16) != hash_) return bad("record of another fit");
  const uint64_t n = get<uint64_t>(b, 32);
  if (n != b.size() - kHeaderBytes) return bad("truncated");
  if (get<uint64_t>(b, 40) != fitting::obsfile_hash64(b.data() + kHeaderBytes, n)) return bad("checksum mismatch");
  return fitting::TileBytes(b.begin() + kHeaderBytes, b.end());
}

Status TileStore::write(int pass, int tile, const fitting::TileBytes& payload) const {
  std::string b(kHeaderBytes, '\0');
  std::memcpy(b.data(), kMagic, 8);
  put<uint32_t>(b, 8, kVersion);
  put<uint32_t>(b, 12, static_cast<uint32_t>(pass));
  put<uint64_t>(b, 16, hash_);
  put<uint32_t>(b, 24, static_cast<uint32_t>(tile));
  put<uint64_t>(b, 32, payload.size());
  put<uint64_t>(b, 40, fitting::obsfile_hash64(payload.data(), payload.size()));
  b.append(reinterpret_cast<const char*>(payload.data()), payload.size());
  return write_file_atomic(record_path(pass, tile), b);
}

Status TileStore::remove() const {
  std::error_code ec;
  fs::remove_all(folder_, ec);
  if (ec) return make_error(ErrorCode::kIo, "removing " + folder_.string() + ": " + ec.message());
  if (fs::is_empty(root_, ec) && !ec) fs::remove(root_, ec);
  return Status::ok();
}

}  // namespace vdrig::cluster

// Durable records of finished tiles of a fit, so that a killed job resumes with the tiles not yet done
// (docs/scale.md). A store is a folder (by default beside the output map: `maps/<model>.exr.tiles/`) holding one
// subfolder per fit identity, named by the 64-bit hash of its fingerprint (the fit's model and options,
// fitting::fit_options_fingerprint, and the observation file's identity): records of another fit live elsewhere and
// are never mixed in. The subfolder's `fit.txt` holds the fingerprint's text.
//
// Record `p<pass>_<tile, 6 digits>.rec`: a 48-byte header (magic "VDRIGTIL", u32 version 1, u32 pass, u64 fingerprint
// hash, u32 tile, u32 0, u64 payload bytes, u64 payload hash64) then the payload (fitting::TileBytes). Written
// atomically (temporary, fsync, rename, fsync of the folder: core/file_write.hpp), so a record on disk is complete;
// one whose header or checksum does not match is refused (kCorrupt) and the tile fitted again.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/tiled_fit.hpp"

namespace vdrig::cluster {

class TileStore {
 public:
  /// Opens (creating it when missing) the store of `fingerprint` under `root`. `create_description`: write fit.txt
  /// (one process of a job does).
  static Result<TileStore> open(const std::filesystem::path& root, const std::string& fingerprint,
                                bool create_description);

  const std::filesystem::path& folder() const { return folder_; }
  uint64_t fingerprint_hash() const { return hash_; }
  std::filesystem::path record_path(int pass, int tile) const;

  /// The record of (pass, tile); kNotFound when absent, kCorrupt when it is not a complete record of this fit.
  Result<fitting::TileBytes> read(int pass, int tile) const;
  /// Records it durably.
  Status write(int pass, int tile, const fitting::TileBytes& payload) const;
  /// Removes this fit's records and its folder (after the map is written), and `root` when it is then empty.
  Status remove() const;

 private:
  std::filesystem::path root_, folder_;
  uint64_t hash_ = 0;
};

}  // namespace vdrig::cluster

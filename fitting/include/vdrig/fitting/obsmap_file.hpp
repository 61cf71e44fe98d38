// Out-of-core observation map: a tiled, versioned binary file (format: docs/obsmap.md) written view by view with
// bounded memory and read back one tile at a time.
//
// Why: a 512 x 512 map over 289 views holds 75 M observations (1.9 GB); the in-memory ObservationMap does not fit
// a small acquisition PC. The writer spills each view's observations, cut into tiles, to an anonymous temporary
// file, and finish() transposes them tile by tile into texel-major tiles: peak memory is one view's observations
// plus one tile's (S x T x 25 B + tile^2 x views x 25 B), whatever the map's size.
//
// Observations are computed by observe_texel (obsmap.hpp), the same function add_view uses, and stored as 32-bit
// floats: a file read back gives bit-identical observations to the in-memory map built from the same views.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/obsmap.hpp"

namespace vdrig::fitting {

/// The version written. 2 (2026-12-05): grazing samples whose pixel footprint is wider than a texel are flagged
/// kObsCoarse (obsmap.hpp) instead of stored as observations; the layout is version 1's. A reader takes 1 and 2
/// (kObsFileOldestVersion): a version-1 file reads as it was written, its grazing samples unflagged, and a session's
/// cached map of an older version is rebuilt (pipeline::session_obsmap_file).
inline constexpr uint32_t kObsFileVersion = 2;
inline constexpr uint32_t kObsFileOldestVersion = 1;

enum class ObsCompression : uint32_t { kNone = 0, kZstd = 1 };

struct ObsFileOptions {
  int tile_size = 32;  // texels per tile side (edge tiles are smaller)
  ObsCompression compression = ObsCompression::kZstd;
  /// 1..max, or zstd's fast levels kMinZstdLevel..-1 (faster, larger; also used for the spill when below its 1).
  int zstd_level = 3;
  static constexpr int kMinZstdLevel = -50;
  /// Folder of the anonymous spill file; empty: the output file's folder (same disk as the result).
  std::filesystem::path spill_dir;
  /// Test/fault-injection hook called before every file write with the file and byte count; a failed Status is
  /// returned as the write's failure (e.g. kNoSpace to simulate a full disk).
  std::function<Status(const std::filesystem::path& file, size_t bytes)> before_write;
  /// A part of a file (the MPI build, cluster/): when end_tile_row >= 0, only tile rows [first_tile_row,
  /// end_tile_row) are sampled and written, to a part file (magic "VDRIGOBP", not readable by ObsMapReader) that
  /// assemble_obsmap_parts joins with the other parts into the file the whole writer would have written.
  int first_tile_row = 0;
  int end_tile_row = -1;

  bool is_valid(std::string* why) const;
};

/// What the file's header says.
struct ObsFileHeader {
  uint32_t version = kObsFileVersion;
  ObservationMapSpec spec;
  int views = 0;
  int tile_size = 32;
  ObsCompression compression = ObsCompression::kNone;
  int tiles_s = 0;  // tiles across s (ceil(texels_s / tile_size))
  int tiles_t = 0;
  uint64_t file_bytes = 0;
  uint64_t stored_tile_bytes = 0;  // sum of the tiles as stored (compressed or not)
  uint64_t raw_tile_bytes = 0;     // sum of the tiles uncompressed
  /// hash64 of the tile index, which holds every tile's checksum: with the sizes above, the file's content
  /// identity (a restartable fit ties its tile records to it, cluster/).
  uint64_t index_checksum = 0;
};

/// One tile read from a file: texels [s0, s0 + width) x [t0, t0 + height), every view. Texel coordinates are the
/// map's (global), as ObservationMap's.
class ObsTile {
 public:
  ObsTile() = default;
  int s0() const { return s0_; }
  int t0() const { return t0_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int views() const { return views_; }
  bool contains(int s, int t) const { return s >= s0_ && s < s0_ + width_ && t >= t0_ && t < t0_ + height_; }

  /// As ObservationMap::texel: the valid observations of (s, t), leaving out `held_out` views (sorted).
  TexelObservations texel(int s, int t, const std::vector<int>& held_out = {}) const;
  /// As ObservationMap::observation: one stored observation whatever its flag.
  uint8_t observation(int s, int t, int view, Eigen::Vector3f* rgb, Eigen::Vector3f* direction) const;
  uint8_t flag(int s, int t, int view) const { return flags_[index(s, t, view)]; }

 private:
  friend class ObsMapReader;
  size_t index(int s, int t, int view) const;
  int s0_ = 0, t0_ = 0, width_ = 0, height_ = 0, views_ = 0;
  std::vector<float> radiance_;   // 3 per observation, [texel][view][rgb]
  std::vector<float> direction_;  // 3 per observation
  std::vector<uint8_t> flags_;
};

/// Builds an observation-map file view by view. Views may come in any order, each exactly once; nothing is
/// visible at `path` until finish() succeeds (written to a temporary file beside it, fsynced, renamed).
/// Destroying an unfinished writer leaves no files behind.
class ObsMapWriter {
 public:
  static Result<ObsMapWriter> create(const std::filesystem::path& path, const ObservationMapSpec& spec, int views,
                                     const ObsFileOptions& options = {});
  ObsMapWriter(ObsMapWriter&&) noexcept;
  ObsMapWriter& operator=(ObsMapWriter&&) noexcept;
  ~ObsMapWriter();

  /// Samples view `view` into every texel (observe_texel) and spills it. Parallel over texel rows.
  Status add_view(int view, const ViewInput& input);
  /// Copies view `view` of an in-memory map (same spec and view count).
  Status add_view(int view, const ObservationMap& map);
  /// A view in which every texel was seen from the same direction (RTI: a fixed camera and one light direction per
  /// photograph, the light taking the place of the camera): texel (s, t) gets pixel (s, t) of `radiance_rgb`
  /// (CV_32FC3, R G B, texels_t rows x texels_s columns), `direction` (unit) and flag kObsValid, or kObsClipped
  /// where `clip_mask` (empty, or CV_8UC1 of the same size) is non-zero.
  Status add_shared_direction_view(int view, const cv::Mat& radiance_rgb, const Eigen::Vector3f& direction,
                                   const cv::Mat& clip_mask = {});
  /// Transposes the spilled views into tiles, writes the index and header, and renames into place.
  Status finish();

  const ObservationMapSpec& spec() const;
  int views() const;

 private:
  struct Impl;
  explicit ObsMapWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Reads an observation-map file a tile at a time. open() checks the header and index (magic, version, sizes,
/// checksums); read_tile() checks the tile's checksum and size. Reads use pread: a const reader may be shared by
/// threads.
class ObsMapReader {
 public:
  static Result<ObsMapReader> open(const std::filesystem::path& path);
  ObsMapReader(ObsMapReader&&) noexcept;
  ObsMapReader& operator=(ObsMapReader&&) noexcept;
  ~ObsMapReader();

  const ObsFileHeader& header() const;
  const ObservationMapSpec& spec() const { return header().spec; }
  int views() const { return header().views; }
  int tiles_s() const { return header().tiles_s; }
  int tiles_t() const { return header().tiles_t; }

  /// Tile (tile_s, tile_t) in tile coordinates; kInvalidArgument when out of range, kCorrupt/kIo when unreadable.
  Result<ObsTile> read_tile(int tile_s, int tile_t) const;
  /// The tile holding texel (s, t).
  Result<ObsTile> read_tile_of_texel(int s, int t) const;
  /// The whole map in memory (small maps; needs S x T x views x 25 B).
  Result<ObservationMap> read_all() const;

 private:
  struct Impl;
  explicit ObsMapReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// The format's checksum (docs/obsmap.md, "hash64"), for tools and tests that write or repair a file by hand.
uint64_t obsfile_hash64(const void* data, size_t n);

/// Joins part files (ObsFileOptions::end_tile_row), which together hold every tile row once, into the file at
/// `path`, byte for byte the file one ObsMapWriter would have written from the same views (tiles copied in index
/// order, each checked against its checksum). Written as the writer writes (temporary, fsync, rename). Errors:
/// kCorrupt for a part that is damaged or does not belong with the others, kInvalidArgument when rows are missing
/// or held twice, kIo/kNoSpace for I/O.
Status assemble_obsmap_parts(const std::vector<std::filesystem::path>& parts, const std::filesystem::path& path);

/// Writes an in-memory map to `path` (ObsMapWriter fed view by view).
Status write_obsmap_file(const ObservationMap& map, const std::filesystem::path& path,
                         const ObsFileOptions& options = {});

}  // namespace vdrig::fitting

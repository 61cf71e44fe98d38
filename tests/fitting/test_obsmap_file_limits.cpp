// .vdobs headers whose dimensions are well formed (checksums right) but would make a reader allocate without bound
// (issue #18, found again by fuzz/fuzz_vdobs): open() refuses them with kCorrupt before allocating, and the writer
// refuses to write what the reader would refuse. Every input in fuzz/regressions/vdobs/ opens and reads to values
// or errors.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::fitting {
namespace {
namespace fs = std::filesystem;

class ObsFileLimits : public ::testing::Test {
 protected:
  const test::TempDir dir_{"fitting_obsfile_limits"};
};

template <typename T>
void put(std::string& buf, size_t at, T v) {
  std::memcpy(buf.data() + at, &v, sizeof v);
}

struct Dimensions {
  int32_t texels_s, texels_t, views, tile_size;
};

/// A file with a valid header and index (docs/obsmap.md) for `d`: one stored tile of `tile_bytes` when the grid
/// has one tile, else an empty index; checksums computed as the writer does.
std::string vdobs_file(const Dimensions& d, const std::string& tile_bytes) {
  std::string f(128, '\0');
  std::memcpy(f.data(), "VDRIGOBS", 8);
  put<uint32_t>(f, 8, 1);
  put<uint32_t>(f, 12, 128);
  put<int32_t>(f, 16, d.texels_s);
  put<int32_t>(f, 20, d.texels_t);
  put<int32_t>(f, 24, d.views);
  put<int32_t>(f, 28, d.tile_size);
  put<double>(f, 32, 1000.0);
  put<double>(f, 40, 1000.0);
  put<uint32_t>(f, 48, 1);  // zstd
  put<uint32_t>(f, 52, 1);  // record layout
  const uint32_t tiles_s = (d.texels_s + d.tile_size - 1) / d.tile_size;
  const uint32_t tiles_t = (d.texels_t + d.tile_size - 1) / d.tile_size;
  put<uint32_t>(f, 56, tiles_s);
  put<uint32_t>(f, 60, tiles_t);
  std::string index;
  if (uint64_t{tiles_s} * tiles_t == 1) {
    index.assign(24, '\0');
    put<uint64_t>(index, 0, 128);
    put<uint64_t>(index, 8, tile_bytes.size());
    put<uint64_t>(index, 16, obsfile_hash64(tile_bytes.data(), tile_bytes.size()));
  }
  put<uint64_t>(f, 64, 128 + tile_bytes.size());
  put<uint64_t>(f, 72, uint64_t{24} * tiles_s * tiles_t);
  put<uint64_t>(f, 80, obsfile_hash64(index.data(), index.size()));
  put<uint64_t>(f, 120, obsfile_hash64(f.data(), 120));
  return f + tile_bytes + index;
}

/// A zstd frame header claiming `content_bytes` (single segment, 8-byte content size) and one empty last block.
std::string zstd_frame_claiming(uint64_t content_bytes) {
  std::string z = {'\x28', '\xB5', '\x2F', '\xFD', '\xE0'};
  z.append(8, '\0');
  put<uint64_t>(z, 5, content_bytes);
  z += std::string{'\x01', '\x00', '\x00'};
  return z;
}

void write(const fs::path& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

TEST_F(ObsFileLimits, HugeDimensionsAreRefusedAtOpenNotBadAlloc) {
  // 4096 x 4096 texels x 2^20 views in one tile: the frame claims exactly that size (4.4e14 bytes), so the
  // decompressed-size check passed and read_tile threw std::bad_alloc.
  const Dimensions huge{4096, 4096, 1 << 20, 4096};
  write(dir_ / "huge.vdobs", vdobs_file(huge, zstd_frame_claiming(uint64_t{4096} * 4096 * (1 << 20) * 25)));
  auto reader = ObsMapReader::open(dir_ / "huge.vdobs");
  ASSERT_FALSE(reader) << "opened a map whose one tile needs 440 TB";
  EXPECT_EQ(reader.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(reader.error().message.find("exceeds the reader's limit"), std::string::npos) << reader.error().message;
}

TEST_F(ObsFileLimits, TileCountIsCheckedAgainstTheFileBeforeItOverflows) {
  // 2^20 x 2^20 tiles of one texel: the count overflowed int (to 0), so an empty index was accepted.
  write(dir_ / "many.vdobs", vdobs_file({1 << 20, 1 << 20, 1, 1}, ""));
  auto reader = ObsMapReader::open(dir_ / "many.vdobs");
  ASSERT_FALSE(reader);
  EXPECT_EQ(reader.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(reader.error().message.find("truncated"), std::string::npos) << reader.error().message;
}

TEST_F(ObsFileLimits, WriterRefusesTilesTheReaderWouldRefuse) {
  ObservationMapSpec spec;
  spec.texels_s = spec.texels_t = 64;
  ObsFileOptions options;
  options.tile_size = 64;
  auto writer = ObsMapWriter::create(dir_ / "big.vdobs", spec, 20000, options);  // 2 GB per tile
  ASSERT_FALSE(writer);
  EXPECT_EQ(writer.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(writer.error().message.find("smaller tile size"), std::string::npos) << writer.error().message;
  options.tile_size = 16;  // 128 MB per tile: fine
  EXPECT_TRUE(ObsMapWriter::create(dir_ / "big.vdobs", spec, 20000, options));
}

TEST_F(ObsFileLimits, MapOfNoViewsReadsEmptyTiles) {
  // Found by fuzz_vdobs: its tiles are empty, and read_tile passed their null data pointers to memcpy (undefined
  // behaviour, reported by the ASan + UBSan build).
  ObservationMapSpec spec;
  spec.texels_s = 3;
  spec.texels_t = 2;
  ASSERT_TRUE(write_obsmap_file(ObservationMap(spec, 0), dir_ / "none.vdobs"));
  auto reader = ObsMapReader::open(dir_ / "none.vdobs");
  ASSERT_TRUE(reader) << reader.error().describe();
  auto tile = reader->read_tile(0, 0);
  ASSERT_TRUE(tile) << tile.error().describe();
  EXPECT_EQ(tile->views(), 0);
  EXPECT_EQ(tile->texel(1, 1).size(), 0u);
}

TEST_F(ObsFileLimits, FuzzRegressionsOpenAndReadToValuesOrErrors) {
  const fs::path folder = fs::path(VDRIG_SOURCE_DIR) / "fuzz" / "regressions" / "vdobs";
  if (!fs::is_directory(folder)) GTEST_SKIP() << "no " << folder;
  for (const auto& entry : fs::directory_iterator(folder)) {
    EXPECT_NO_THROW({
      auto reader = ObsMapReader::open(entry.path());
      if (reader)
        for (int t = 0; t < std::min(reader->tiles_t(), 4); ++t)
          for (int s = 0; s < std::min(reader->tiles_s(), 4); ++s) (void)reader->read_tile(s, t);
    }) << entry.path();
  }
}

}  // namespace
}  // namespace vdrig::fitting

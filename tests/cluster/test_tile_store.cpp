// TileStore (cluster/tile_store.hpp): records come back as written; a damaged record, or one of another fit or tile,
// is refused rather than mixed into a resumed fit.
#include <gtest/gtest.h>

#include <fstream>

#include "vdrig/cluster/tile_store.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::cluster {
namespace {
namespace fs = std::filesystem;

TEST(TileStore, RecordsRoundTripAndStaleOrDamagedOnesAreRefused) {
  test::TempDir dir("tile_store");
  auto a = TileStore::open(dir / "map.exr.tiles", "model=phong:1;obs=A", true);
  auto b = TileStore::open(dir / "map.exr.tiles", "model=phong:1;obs=B", true);
  ASSERT_TRUE(a && b);
  EXPECT_NE(a->folder(), b->folder()) << "two fits never share a folder";
  const fitting::TileBytes payload = {1, 2, 3, 4, 5, 250};
  ASSERT_TRUE(a->write(0, 7, payload));
  auto back = a->read(0, 7);
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_EQ(back.value(), payload);
  EXPECT_EQ(a->read(1, 7).error().code, ErrorCode::kNotFound);

  // Another fit's record placed where this fit looks (copied by hand, or a hash collision): refused.
  ASSERT_TRUE(b->write(0, 7, payload));
  fs::copy_file(b->record_path(0, 7), a->record_path(0, 8));
  fs::copy_file(b->record_path(0, 7), a->record_path(0, 7), fs::copy_options::overwrite_existing);
  auto stale = a->read(0, 7);
  ASSERT_FALSE(stale);
  EXPECT_EQ(stale.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(stale.error().message.find("another fit"), std::string::npos) << stale.error().message;
  EXPECT_FALSE(a->read(0, 8)) << "a record of another tile";

  // A flipped payload byte fails the checksum.
  ASSERT_TRUE(a->write(0, 7, payload));
  {
    std::fstream f(a->record_path(0, 7), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(48 + 2);
    f.put(static_cast<char>(99));
  }
  auto damaged = a->read(0, 7);
  ASSERT_FALSE(damaged);
  EXPECT_NE(damaged.error().message.find("checksum"), std::string::npos) << damaged.error().message;

  // fit.txt ties the folder to its fingerprint's text.
  std::ifstream description(a->folder() / "fit.txt");
  std::string line;
  std::getline(description, line);
  EXPECT_EQ(line, "model=phong:1;obs=A");
  ASSERT_TRUE(a->remove());
  EXPECT_FALSE(fs::exists(a->folder()));
  EXPECT_TRUE(fs::exists(b->folder()));
}

}  // namespace
}  // namespace vdrig::cluster

// core: input files are read only when they are regular files (issue #18: a directory given as a JSON input
// aborted, a FIFO frame hung `vdrig hdr`), JSON errors name the line and column, and an oversized PNG is refused
// from its header.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {
namespace fs = std::filesystem;

class FileRead : public ::testing::Test {
 protected:
  void write(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }
  const test::TempDir dir_{"core_file_read"};
};

TEST_F(FileRead, JsonFileReadsAnObject) {
  write(dir_ / "a.json", R"({"x": 1})");
  auto j = read_json_file(dir_ / "a.json");
  ASSERT_TRUE(j) << j.error().describe();
  EXPECT_EQ((*j)["x"], 1);
}

// nlohmann::json keeps the last of a repeated key without a word: a rig config setting "port" twice would silently
// drive the second. Every repeated key is refused, named with the path of its object.
TEST_F(FileRead, JsonFileWithARepeatedKeyIsRefusedNamingEveryKeyAndItsPath) {
  write(dir_ / "dup.json", R"({"stage": {"backend": "modbus-tcp", "port": 502, "pan": {"unit": 1, "unit": 2},
                               "port": 503},
                              "list": [{"a": 1}, {"b": 1, "b": 2}], "stage": {}})");
  auto j = read_json_file(dir_ / "dup.json");
  ASSERT_FALSE(j) << "accepted: " << j->dump();
  EXPECT_EQ(j.error().code, ErrorCode::kCorrupt);
  for (const char* named : {"duplicate key \"port\" in stage", "duplicate key \"unit\" in stage.pan",
                            "duplicate key \"b\" in list[1]", "duplicate key \"stage\" at the top level"})
    EXPECT_NE(j.error().message.find(named), std::string::npos) << named << " not in: " << j.error().message;
  // The same key in different objects is no repetition.
  write(dir_ / "ok.json", R"({"pan": {"unit": 1}, "tilt": {"unit": 2}, "list": [{"unit": 3}, {"unit": 4}]})");
  EXPECT_TRUE(read_json_file(dir_ / "ok.json"));
}

TEST_F(FileRead, DirectoryFifoAndMissingFileAreErrorsNotAbortsOrHangs) {
  fs::create_directories(dir_ / "dir.json");
  auto d = read_json_file(dir_ / "dir.json");
  ASSERT_FALSE(d);
  EXPECT_EQ(d.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(d.error().message.find("is a directory"), std::string::npos) << d.error().message;

  ASSERT_EQ(::mkfifo((dir_ / "fifo.json").c_str(), 0600), 0);
  auto f = read_json_file(dir_ / "fifo.json");  // would block forever in open() without O_NONBLOCK
  ASSERT_FALSE(f);
  EXPECT_NE(f.error().message.find("is a FIFO"), std::string::npos) << f.error().message;

  auto m = read_json_file(dir_ / "missing.json");
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().code, ErrorCode::kNotFound);
}

TEST_F(FileRead, ParseErrorsNameLineAndColumnAndTheTopLevelMustBeAnObject) {
  write(dir_ / "bad.json", "{\n  \"x\": 1,\n  oops\n}\n");
  auto b = read_json_file(dir_ / "bad.json");
  ASSERT_FALSE(b);
  EXPECT_EQ(b.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(b.error().message.find("line 3, column"), std::string::npos) << b.error().message;

  write(dir_ / "array.json", "[1, 2]");
  auto a = read_json_file(dir_ / "array.json");
  ASSERT_FALSE(a);
  EXPECT_EQ(a.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(a.error().message.find("expected a JSON object"), std::string::npos) << a.error().message;
}

// Found by fuzz_manifest: nlohmann reports a number beyond a double's range as out_of_range.406, not as a
// parse_error, and read_json_file let it escape (std::terminate).
TEST_F(FileRead, ANumberBeyondADoublesRangeIsACorruptFileNotAnAbort) {
  write(dir_ / "huge.json", R"({"format_version": 1e999})");
  auto h = read_json_file(dir_ / "huge.json");
  ASSERT_FALSE(h);
  EXPECT_EQ(h.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(h.error().message.find("number overflow"), std::string::npos) << h.error().message;
}

TEST_F(FileRead, ImageReadersRefuseFifosAndDirectories) {
  ASSERT_EQ(::mkfifo((dir_ / "frame.png").c_str(), 0600), 0);
  auto png = read_png(dir_ / "frame.png");  // cv::imread blocked here, waiting for a writer
  ASSERT_FALSE(png);
  EXPECT_NE(png.error().message.find("is a FIFO"), std::string::npos) << png.error().message;
  ASSERT_EQ(::mkfifo((dir_ / "view.exr").c_str(), 0600), 0);
  auto exr = read_exr(dir_ / "view.exr");
  ASSERT_FALSE(exr);
  EXPECT_NE(exr.error().message.find("is a FIFO"), std::string::npos) << exr.error().message;
  fs::create_directories(dir_ / "d.exr");
  auto dexr = read_exr(dir_ / "d.exr");
  ASSERT_FALSE(dexr);
  EXPECT_NE(dexr.error().message.find("is a directory"), std::string::npos) << dexr.error().message;
}

TEST_F(FileRead, OversizedPngIsRefusedFromItsHeaderBeforeDecoding) {
  // A valid small PNG whose IHDR is patched to claim 12000 x 12000: refused by its header, never decoded.
  ASSERT_TRUE(write_png(dir_ / "small.png", cv::Mat(4, 4, CV_8UC3, cv::Scalar::all(7))));
  std::ifstream in(dir_ / "small.png", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 24u);
  const unsigned char side[4] = {0x00, 0x00, 0x2e, 0xe0};  // 12000, big-endian
  for (int i = 0; i < 4; ++i) bytes[16 + i] = bytes[20 + i] = static_cast<char>(side[i]);
  write(dir_ / "huge.png", bytes);
  auto huge = read_png(dir_ / "huge.png");
  ASSERT_FALSE(huge);
  EXPECT_EQ(huge.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(huge.error().message.find("12000x12000"), std::string::npos) << huge.error().message;
  auto small = read_png(dir_ / "small.png");
  ASSERT_TRUE(small) << small.error().describe();
  EXPECT_EQ(small->cols, 4);
}

}  // namespace
}  // namespace vdrig

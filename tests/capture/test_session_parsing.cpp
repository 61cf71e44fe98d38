// Session::open on damaged journals and manifests (issue #18, found again by fuzz/fuzz_journal and fuzz_manifest):
// a wrong-typed or out-of-range field is kCorrupt naming its line, never an uncaught json exception or an
// unchecked cast; and every input the fuzzers kept in fuzz/regressions/{journal,manifest}/ opens to a value or an
// error.
#include <gtest/gtest.h>

#include <fstream>

#include "test_support.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

void write(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

/// A valid frame line of view 0 as the writer makes it.
json frame_line() {
  FrameRecord r;
  r.file = "frames/view_0000_e00.png";
  r.exposure_s = 0.01;
  return r.to_json();
}

/// Opens a two-view session whose journal is `journal`.
Result<Session> open_with_journal(const fs::path& dir, const std::string& journal) {
  fs::remove_all(dir);
  if (auto s = Session::create(dir, testing::manifest_with_views(2)); !s) return s.error();
  write(dir / "journal.jsonl", journal);
  return Session::open(dir);
}

TEST(SessionParsing, WrongTypedJournalLinesAreCorruptNotExceptions) {
  vdrig::test::TempDir tmp("session_parsing_journal");
  // A view index that is a number but names no view (1e30, 2^32, -1) is ignored with a warning, not corrupt:
  // test_session_journal_range covers those. Here: fields of the wrong type.
  json float_bits = frame_line(), negative_sequence = frame_line();
  float_bits["bits"] = 8.5;
  negative_sequence["sequence"] = -1;
  const std::vector<std::string> bad_lines = {
      R"({"type":"view_complete","view":[0]})",
      R"({"type":7})",
      R"([{"type":"frame"}])",
      R"("view_complete")",
      R"({"type":"view_complete","view":0,"frames":"2"})",
      float_bits.dump(),
      negative_sequence.dump(),
  };
  for (const std::string& line : bad_lines) {
    Result<Session> s = Error{ErrorCode::kInternal, "not run"};
    ASSERT_NO_THROW(s = open_with_journal(tmp.path(), frame_line().dump() + "\n" + line + "\n")) << line;
    ASSERT_FALSE(s) << line;
    EXPECT_EQ(s.error().code, ErrorCode::kCorrupt) << line;
    EXPECT_NE(s.error().message.find("journal line 2"), std::string::npos) << line << ": " << s.error().message;
  }
  // The same fields, well typed, still open.
  auto good =
      open_with_journal(tmp.path(), frame_line().dump() + "\n" + R"({"type":"view_complete","view":0,"frames":1})" +
                                        "\n" + R"({"type":"event","note":7})" + "\n");
  ASSERT_TRUE(good) << good.error().describe();
  EXPECT_TRUE(good->view_complete(0));
  EXPECT_EQ(good->frames_of_view(0).size(), 1u);
}

TEST(SessionParsing, ManifestIntegersMustBeIntegersThatFit) {
  vdrig::test::TempDir tmp("session_parsing_manifest");
  const json valid = testing::manifest_with_views(2).to_json();
  json fractional_version = valid, wide_index = valid, float_index = valid;
  fractional_version["format_version"] = 1.5;      // was read as 1
  wide_index["views"][0]["index"] = 4294967296ll;  // was read as 0
  float_index["views"][1]["index"] = 1e300;
  for (const json& manifest : {fractional_version, wide_index, float_index}) {
    Result<Manifest> m = Error{ErrorCode::kInternal, "not run"};
    ASSERT_NO_THROW(m = Manifest::from_json(manifest));
    ASSERT_FALSE(m) << manifest.dump();
    EXPECT_EQ(m.error().code, ErrorCode::kCorrupt);
  }
  EXPECT_TRUE(Manifest::from_json(valid));
}

/// Every file in fuzz/regressions/<target>/ fed as `file_name` of a session folder opens to a value or an error.
void replay(const std::string& target, const std::string& file_name) {
  const fs::path folder = fs::path(VDRIG_SOURCE_DIR) / "fuzz" / "regressions" / target;
  if (!fs::is_directory(folder)) GTEST_SKIP() << "no " << folder;
  vdrig::test::TempDir tmp("session_parsing_replay_" + target);
  int replayed = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    fs::remove_all(tmp.path());
    ASSERT_TRUE(Session::create(tmp.path(), testing::manifest_with_views(2)));
    fs::copy_file(entry.path(), tmp.path() / file_name, fs::copy_options::overwrite_existing);
    EXPECT_NO_THROW((void)Session::open(tmp.path())) << entry.path();
    ++replayed;
  }
  EXPECT_GT(replayed, 0);
}

TEST(SessionParsing, FuzzJournalRegressionsOpenToAValueOrAnError) { replay("journal", "journal.jsonl"); }
TEST(SessionParsing, FuzzManifestRegressionsOpenToAValueOrAnError) { replay("manifest", "manifest.json"); }

}  // namespace
}  // namespace vdrig::capture

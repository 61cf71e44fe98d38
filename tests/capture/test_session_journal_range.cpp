// Journal lines naming views outside the manifest (99999, -1, 1e30, 2.5) do not count as views: they are ignored
// with a warning, for frame lines and view_complete lines alike. A manifest that plans no views is refused at load.
#include <gtest/gtest.h>

#include <fstream>

#include "test_support.hpp"
#include "vdrig/capture/session.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

void append_lines(const fs::path& journal, const std::vector<std::string>& lines) {
  std::ofstream out(journal, std::ios::app | std::ios::binary);
  for (const auto& l : lines) out << l << "\n";
}

std::string frame_line(const std::string& view) {
  return R"({"type":"frame","view":)" + view +
         R"(,"bracket":0,"file":"frames/view_0000_e00.png","exposure_s":0.01,)"
         R"("commanded":{"pan_deg":0,"tilt_deg":0},"measured":{"pan_deg":0,"tilt_deg":0}})";
}

TEST(SessionJournalRange, ViewsOutsideTheManifestAreIgnoredNotCounted) {
  vdrig::test::TempDir dir("journal_range");
  {
    auto s = Session::create(dir.path(), testing::manifest_with_views(3));
    ASSERT_TRUE(s) << s.error().describe();
  }
  const fs::path journal = SessionLayout(dir.path()).journal_file();
  std::vector<std::string> lines;
  for (const char* bad : {"99999", "-1", "1e30", "3", "2.5", "18446744073709551615", "-9223372036854775808"}) {
    lines.push_back(frame_line(bad));
    lines.push_back(std::string(R"({"type":"view_complete","view":)") + bad + R"(,"frames":1})");
  }
  lines.push_back(R"({"type":"view_complete","frames":1})");  // names no view
  lines.push_back(frame_line("1"));
  lines.push_back(R"({"type":"view_complete","view":1,"frames":1})");
  append_lines(journal, lines);

  auto s = Session::open(dir.path());
  ASSERT_TRUE(s) << s.error().describe();
  EXPECT_EQ(s->completed_view_count(), 1);  // only view 1: the 8 other completions name no view of the manifest
  EXPECT_TRUE(s->view_complete(1));
  EXPECT_FALSE(s->view_complete(-1));
  EXPECT_FALSE(s->view_complete(99999));
  ASSERT_EQ(s->frames().size(), 1u);  // only view 1's frame line
  EXPECT_EQ(s->frames()[0].view, 1);
  for (const auto& f : s->frames()) {
    EXPECT_GE(f.view, 0);
    EXPECT_LT(f.view, 3);
  }
}

TEST(SessionJournalRange, AManifestWithoutViewsIsRefusedAtLoad) {
  vdrig::test::TempDir dir("journal_noviews");
  {
    auto s = Session::create(dir.path(), testing::manifest_with_views(3));
    ASSERT_TRUE(s) << s.error().describe();
  }
  const fs::path manifest = SessionLayout(dir.path()).manifest_file();
  json j;
  {
    std::ifstream in(manifest);
    j = json::parse(in);
  }
  j["views"] = json::array();
  testing::write_text(manifest, j.dump(2));
  auto s = Session::open(dir.path());
  ASSERT_FALSE(s) << "a session with no views opened";
  EXPECT_EQ(s.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(s.error().message.find("no views"), std::string::npos) << s.error().message;

  auto m = Manifest::from_json(j);
  EXPECT_FALSE(m);
  // Nor is one created.
  vdrig::test::TempDir other("journal_noviews_create");
  Manifest empty = testing::manifest_with_views(3);
  empty.views.clear();
  EXPECT_FALSE(Session::create(other.path(), empty));
}

}  // namespace
}  // namespace vdrig::capture

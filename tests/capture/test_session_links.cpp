// Sessions in a hostile file system (issue 23): session folders may be writable by other users while vdrig (often
// root) writes into them. A symbolic link planted at a frame, at frames/, at journal.jsonl or manifest.json is an
// error naming it, never written (or read) through; a dangling link's target is not created. Readers never write:
// opening a session whose journal ends in a torn line leaves the file as it is; the writer (open_for_capture, under
// the session lock) cuts the line off.
#include <gtest/gtest.h>

#include <fstream>

#include "test_support.hpp"
#include "vdrig/capture/session.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;

Frame small_frame() {
  Frame frame;
  frame.image = cv::Mat(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  frame.exposure_s = 0.01;
  return frame;
}

std::string file_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

/// A session of `views` planned views in root/S with views 0..complete-1 captured (one frame each).
fs::path session_with_complete_views(const vdrig::test::TempDir& root, int views, int complete) {
  const fs::path dir = root.path() / "S";
  auto s = Session::create(dir, testing::manifest_with_views(views));
  EXPECT_TRUE(s) << s.error().describe();
  for (int v = 0; v < complete; ++v) {
    EXPECT_TRUE(s->append_frame(v, 0, small_frame(), false));
    EXPECT_TRUE(s->mark_view_complete(v, 1));
  }
  return dir;
}

TEST(SessionLinks, AFrameLinkPlantedAtTheNextFrameIsRefusedNotWrittenThrough) {
  vdrig::test::TempDir root("links_frame");
  const fs::path dir = session_with_complete_views(root, 6, 4);
  const fs::path victim = root.path() / "victim";
  write_text(victim, "precious");
  const fs::path planted = SessionLayout(dir).frame_file(4, 0);
  fs::create_symlink("../../victim", planted);

  auto s = Session::open_for_capture(dir);
  ASSERT_TRUE(s) << s.error().describe();
  auto written = s->append_frame(4, 0, small_frame(), false);
  ASSERT_FALSE(written) << "the frame was written through the planted link";
  EXPECT_NE(written.error().message.find(planted.string()), std::string::npos) << written.error().message;
  EXPECT_EQ(file_text(victim), "precious");
  EXPECT_TRUE(fs::is_symlink(planted));
}

TEST(SessionLinks, ADanglingFrameLinkDoesNotCreateItsTarget) {
  vdrig::test::TempDir root("links_dangling");
  const fs::path dir = session_with_complete_views(root, 3, 1);
  const fs::path target = root.path() / "created_by_vdrig";
  fs::create_symlink(target, SessionLayout(dir).frame_file(1, 0));

  auto s = Session::open_for_capture(dir);
  ASSERT_TRUE(s) << s.error().describe();
  EXPECT_FALSE(s->append_frame(1, 0, small_frame(), false));
  EXPECT_FALSE(fs::exists(fs::symlink_status(target))) << "the link's target was created";
}

TEST(SessionLinks, ALinkedFramesFolderIsRefused) {
  vdrig::test::TempDir root("links_frames_dir");
  const fs::path dir = session_with_complete_views(root, 3, 0);
  const fs::path elsewhere = root.path() / "elsewhere";
  fs::create_directories(elsewhere);
  const fs::path frames = SessionLayout(dir).frames_dir();
  fs::remove(frames);
  fs::create_directory_symlink(elsewhere, frames);

  auto s = Session::open_for_capture(dir);
  ASSERT_TRUE(s) << s.error().describe();
  auto written = s->append_frame(0, 0, small_frame(), false);
  ASSERT_FALSE(written);
  EXPECT_NE(written.error().message.find(frames.string()), std::string::npos) << written.error().message;
  EXPECT_TRUE(fs::is_empty(elsewhere));
}

TEST(SessionLinks, ALinkedJournalOrManifestIsAnErrorNamingIt) {
  vdrig::test::TempDir root("links_journal");
  const fs::path dir = session_with_complete_views(root, 3, 1);
  const SessionLayout layout(dir);
  for (const fs::path& linked : {layout.journal_file(), layout.manifest_file()}) {
    const fs::path real = root.path() / ("real_" + linked.filename().string());
    fs::rename(linked, real);
    fs::create_symlink(real, linked);
    auto opened = Session::open(dir);
    ASSERT_FALSE(opened) << linked << " was read through a link";
    EXPECT_NE(opened.error().message.find(linked.string()), std::string::npos) << opened.error().message;
    fs::remove(linked);
    fs::rename(real, linked);
  }
}

TEST(SessionLinks, AppendingToALinkedJournalIsRefused) {
  vdrig::test::TempDir root("links_append");
  const fs::path dir = session_with_complete_views(root, 3, 1);
  auto s = Session::open_for_capture(dir);
  ASSERT_TRUE(s) << s.error().describe();
  const fs::path journal = SessionLayout(dir).journal_file();
  const fs::path victim = root.path() / "victim";
  write_text(victim, "precious");
  fs::remove(journal);
  fs::create_symlink(victim, journal);
  EXPECT_FALSE(s->append_event({{"event", "note"}}));
  EXPECT_EQ(file_text(victim), "precious");
}

TEST(SessionReaders, OpeningASessionWithATornJournalLineLeavesTheFileAlone) {
  vdrig::test::TempDir root("readers_torn");
  const fs::path dir = session_with_complete_views(root, 3, 1);
  const fs::path journal = SessionLayout(dir).journal_file();
  {
    std::ofstream out(journal, std::ios::app | std::ios::binary);
    out << R"({"type":"frame","view":1,"bra)";  // a crash mid-append
  }
  const std::string before = file_text(journal);
  auto reader = Session::open(dir);
  ASSERT_TRUE(reader) << reader.error().describe();
  EXPECT_EQ(reader->completed_view_count(), 1);
  EXPECT_EQ(file_text(journal), before) << "a reader modified the journal";

  // The writer, under the lock, cuts the torn line off; its appends then read back.
  auto writer = Session::open_for_capture(dir);
  ASSERT_TRUE(writer) << writer.error().describe();
  const std::string repaired = file_text(journal);
  EXPECT_EQ(repaired, before.substr(0, before.rfind('\n') + 1));
  ASSERT_TRUE(writer->append_frame(1, 0, small_frame(), false));
  ASSERT_TRUE(writer->mark_view_complete(1, 1));
  auto reread = Session::open(dir);
  ASSERT_TRUE(reread) << reread.error().describe();
  EXPECT_EQ(reread->completed_view_count(), 2);
}

TEST(SessionReaders, ATornLineBehindALinkedJournalIsNotTruncatedThroughIt) {
  vdrig::test::TempDir root("readers_torn_link");
  const fs::path dir = session_with_complete_views(root, 3, 1);
  const fs::path journal = SessionLayout(dir).journal_file();
  const fs::path victim = root.path() / "victim";
  write_text(victim, file_text(journal) + "no newline at the end");
  fs::remove(journal);
  fs::create_symlink(victim, journal);
  const std::string before = file_text(victim);
  EXPECT_FALSE(Session::open(dir));
  EXPECT_EQ(file_text(victim), before);
}

}  // namespace
}  // namespace vdrig::capture

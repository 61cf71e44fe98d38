// Issue 23: a link planted at a session's hdr/ (hdr -> DIR) must not make `vdrig hdr` write its EXRs into DIR, nor
// a link at one HDR file redirect or replace it: the merge fails naming the link and DIR stays empty.
#include <gtest/gtest.h>

#include "small_session.hpp"
#include "vdrig/pipeline/hdr_stage.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

TEST(SessionLinks, ALinkedHdrFolderIsRefusedAndNothingIsWrittenThrough) {
  vdrig::test::TempDir root("links_hdr");
  auto session = test::small_merged_session(root.path() / "S");
  ASSERT_TRUE(session) << session.error().describe();
  const fs::path hdr = session->layout().hdr_dir();
  const fs::path elsewhere = root.path() / "elsewhere";
  fs::create_directories(elsewhere);
  fs::remove_all(hdr);
  fs::create_directory_symlink(elsewhere, hdr);

  HdrMergeOptions force;
  force.force = true;
  const auto merged = merge_session_hdr(session.value(), force);
  ASSERT_FALSE(merged) << "merged through the planted hdr link";
  EXPECT_NE(merged.error().message.find(hdr.string()), std::string::npos) << merged.error().message;
  EXPECT_TRUE(fs::is_empty(elsewhere)) << "EXRs were written into the link's target";
}

TEST(SessionLinks, ALinkAtAnHdrFileIsRefusedAndKept) {
  vdrig::test::TempDir root("links_hdr_file");
  auto session = test::small_merged_session(root.path() / "S");
  ASSERT_TRUE(session) << session.error().describe();
  const fs::path planted = session->layout().hdr_file(0);
  const fs::path target = root.path() / "victim.exr";
  fs::remove(planted);
  fs::create_symlink(target, planted);

  HdrMergeOptions force;
  force.force = true;
  EXPECT_FALSE(merge_session_hdr(session.value(), force));
  EXPECT_TRUE(fs::is_symlink(planted));
  EXPECT_FALSE(fs::exists(fs::symlink_status(target)));
}

}  // namespace
}  // namespace vdrig::pipeline

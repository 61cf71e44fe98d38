// `vdrig session check S [--repair]` (capture/session_check.hpp) and `vdrig capture --resume S --redo VIEWS`
// (issue 23): a damaged frame of a complete view no longer blocks the pipeline. check reports it (exit status 1,
// one line per problem, naming the file); --repair marks the view incomplete through the journal so that
// `capture --resume` re-shoots it; --redo re-shoots chosen views on purpose. --repair also removes stale
// temporaries (a killed fit's obsmap/*.vdobs.tmp-*) and planted links; foreign files are reported, not touched.
#include <gtest/gtest.h>

#include <fstream>

#include "sim_session.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/capture/session_check.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

Frame small_frame() {
  Frame frame;
  frame.image = cv::Mat(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  frame.exposure_s = 0.01;
  return frame;
}

fs::path session_with_complete_views(const vdrig::test::TempDir& root, int views) {
  const fs::path dir = root.path() / "S";
  auto s = Session::create(dir, testing::manifest_with_views(views));
  EXPECT_TRUE(s) << s.error().describe();
  for (int v = 0; v < views; ++v) {
    EXPECT_TRUE(s->append_frame(v, 0, small_frame(), false));
    EXPECT_TRUE(s->mark_view_complete(v, 1));
  }
  return dir;
}

void truncate_to_half(const fs::path& file) { fs::resize_file(file, fs::file_size(file) / 2); }

bool mentions(const SessionCheckReport& report, const fs::path& path) {
  for (const auto& p : report.problems)
    if (p.path == path) return true;
  return false;
}

TEST(SessionCheck, AHealthySessionHasNoProblem) {
  vdrig::test::TempDir root("check_ok");
  const fs::path dir = session_with_complete_views(root, 3);
  auto report = check_session(dir);
  ASSERT_TRUE(report) << report.error().describe();
  EXPECT_TRUE(report->problems.empty()) << report->problems.front().describe();
}

TEST(SessionCheck, ATruncatedFrameIsReportedAndRepairMarksItsViewIncomplete) {
  vdrig::test::TempDir root("check_truncated");
  const fs::path dir = session_with_complete_views(root, 3);
  const fs::path damaged = SessionLayout(dir).frame_file(1, 0);
  truncate_to_half(damaged);
  const std::string journal_before = [&] {
    std::ifstream in(SessionLayout(dir).journal_file());
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();

  auto report = check_session(dir);
  ASSERT_TRUE(report) << report.error().describe();
  ASSERT_TRUE(mentions(report.value(), damaged));
  EXPECT_EQ(report->unrepaired_count(), 1);
  EXPECT_EQ(report->problems.front().view, 1);
  auto unchanged = Session::open(dir);
  ASSERT_TRUE(unchanged);
  EXPECT_TRUE(unchanged->view_complete(1)) << "a check without --repair changed the session";

  auto repaired = check_session(dir, {.repair = true});
  ASSERT_TRUE(repaired) << repaired.error().describe();
  EXPECT_EQ(repaired->unrepaired_count(), 0);
  EXPECT_EQ(repaired->views_marked_incomplete, std::vector<int>{1});
  auto after = Session::open(dir);
  ASSERT_TRUE(after) << after.error().describe();
  EXPECT_FALSE(after->view_complete(1));
  EXPECT_TRUE(after->view_complete(0));
  EXPECT_TRUE(after->frames_of_view(1).empty());
  // The journal was appended to, not rewritten.
  std::ifstream in(SessionLayout(dir).journal_file());
  const std::string journal_after(std::istreambuf_iterator<char>(in), {});
  EXPECT_EQ(journal_after.substr(0, journal_before.size()), journal_before);
  EXPECT_NE(journal_after.find(R"("type":"view_redo")"), std::string::npos);

  auto rechecked = check_session(dir);
  ASSERT_TRUE(rechecked);
  EXPECT_TRUE(rechecked->problems.empty()) << rechecked->problems.front().describe();
}

TEST(SessionCheck, RepairIsRefusedWhileAnotherCapturerHoldsTheLock) {
  vdrig::test::TempDir root("check_locked");
  const fs::path dir = session_with_complete_views(root, 2);
  truncate_to_half(SessionLayout(dir).frame_file(0, 0));
  auto held = lock_session(dir);
  ASSERT_TRUE(held);
  auto repaired = check_session(dir, {.repair = true});
  ASSERT_FALSE(repaired);
  EXPECT_NE(repaired.error().message.find("in use by PID"), std::string::npos) << repaired.error().message;
}

TEST(SessionCheck, LinksAndStaleTemporariesAreRemovedForeignFilesOnlyReported) {
  vdrig::test::TempDir root("check_foreign");
  const fs::path dir = session_with_complete_views(root, 2);
  const SessionLayout layout(dir);
  fs::create_directories(layout.obsmap_dir());
  const fs::path stale = layout.obsmap_dir() / "64x64.vdobs.tmp-a1B2c3";  // a killed fit's
  const fs::path fresh = layout.obsmap_dir() / "32x32.vdobs.tmp-Zz9Yy8";  // a fit writing right now
  std::ofstream(stale) << "partial";
  std::ofstream(fresh) << "partial";
  fs::last_write_time(stale, fs::file_time_type::clock::now() - std::chrono::hours(2));
  const fs::path victim = root.path() / "victim";
  std::ofstream(victim) << "precious";
  const fs::path link = layout.dir() / "calib";
  fs::create_directory_symlink(root.path(), link);
  const fs::path foreign = layout.frames_dir() / "notes.txt";
  std::ofstream(foreign) << "hello";

  auto report = check_session(dir);
  ASSERT_TRUE(report) << report.error().describe();
  EXPECT_TRUE(mentions(report.value(), stale));
  EXPECT_FALSE(mentions(report.value(), fresh));
  EXPECT_TRUE(mentions(report.value(), link));
  EXPECT_TRUE(mentions(report.value(), foreign));
  EXPECT_EQ(report->unrepaired_count(), 3);

  auto repaired = check_session(dir, {.repair = true});
  ASSERT_TRUE(repaired) << repaired.error().describe();
  EXPECT_EQ(repaired->unrepaired_count(), 1);  // the foreign file is the user's to remove
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(fresh));
  EXPECT_FALSE(fs::exists(fs::symlink_status(link)));
  EXPECT_TRUE(fs::exists(root.path() / "victim")) << "the link's target was touched";
  EXPECT_TRUE(fs::exists(foreign));
  auto s = Session::open(dir);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->completed_view_count(), 2);  // no frame was bad: no view to re-shoot
}

TEST(SessionCheck, ATornJournalLineIsReportedAndCutOffOnlyByRepair) {
  vdrig::test::TempDir root("check_torn");
  const fs::path dir = session_with_complete_views(root, 2);
  const fs::path journal = SessionLayout(dir).journal_file();
  std::ofstream(journal, std::ios::app) << R"({"type":"fra)";
  const auto size = fs::file_size(journal);
  auto report = check_session(dir);
  ASSERT_TRUE(report);
  EXPECT_TRUE(mentions(report.value(), journal));
  EXPECT_EQ(fs::file_size(journal), size);
  auto repaired = check_session(dir, {.repair = true});
  ASSERT_TRUE(repaired);
  EXPECT_EQ(repaired->unrepaired_count(), 0);
  EXPECT_LT(fs::file_size(journal), size);
}

// Process level: the CLI over a simulated capture.
class SessionCheckCli : public ::testing::Test {
 protected:
  void SetUp() override {
    cli_ = testing::vdrig_cli();
    ASSERT_FALSE(cli_.empty());
    auto manifest = testing::create_sim_session(dir_, testing::small_sim_config());
    ASSERT_TRUE(manifest) << manifest.error().describe();
    views_ = static_cast<int>(manifest->views.size());
    ASSERT_GE(views_, 2);
    const auto r = run({"capture", "--resume", dir_.string(), "--reserve-mb", "0"});
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  }
  vdrig::test::ProcessRun run(std::vector<std::string> args) const {
    args.insert(args.begin(), cli_);
    return testing::run_process(args);
  }

  vdrig::test::TempDir root_{"check_cli"};
  fs::path dir_ = root_.path() / "S";
  std::string cli_;
  int views_ = 0;
};

TEST_F(SessionCheckCli, CheckRepairAndResumeReshootADamagedView) {
  const fs::path damaged = SessionLayout(dir_).frame_file(1, 0);
  truncate_to_half(damaged);
  auto r = run({"session", "check", dir_.string()});
  EXPECT_NE(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find(damaged.string()), std::string::npos) << r.out << r.err;

  r = run({"session", "check", dir_.string(), "--repair"});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  r = run({"capture", "--resume", dir_.string(), "--reserve-mb", "0"});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  r = run({"session", "check", dir_.string()});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  auto s = Session::open(dir_);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->completed_view_count(), views_);
  EXPECT_TRUE(s->load_image(s->frames_of_view(1).at(0)));
}

TEST_F(SessionCheckCli, RedoReshootsChosenViews) {
  const auto r = run({"capture", "--resume", dir_.string(), "--redo", "0,1", "--reserve-mb", "0"});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  auto after = Session::open(dir_);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->completed_view_count(), views_);
  ASSERT_EQ(after->frames_of_view(1).size(), 1u);
  // View 1 was shot again: its frame has two lines in the journal, with a view_redo line between them.
  std::ifstream in(SessionLayout(dir_).journal_file());
  std::vector<std::string> view1_types;
  for (std::string line; std::getline(in, line);) {
    const json j = json::parse(line);
    if (j.value("view", -1) == 1) view1_types.push_back(j.value("type", ""));
  }
  const std::vector<std::string> expected = {"frame", "view_complete", "view_redo", "frame", "view_complete"};
  EXPECT_EQ(view1_types, expected);

  const auto bad = run({"capture", "--resume", dir_.string(), "--redo", "99999", "--reserve-mb", "0"});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("99999"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace vdrig::capture

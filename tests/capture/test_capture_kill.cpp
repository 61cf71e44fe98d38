// Crash safety: a child process runs a simulated ~150-view capture and is SIGKILLed at 20 random moments; each
// time the session is resumed. At the end every planned view is complete exactly once in the journal with a full
// bracket, and every journaled frame file decodes. Then the same with an injected full disk.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <random>
#include <thread>

#include "sim_session.hpp"
#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/test/kill_when_grown.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

using testing::make_sim_rig;
using testing::small_sim_config;

fs::path create_session(const std::string& name, const std::string& scheme, const std::string& bracket) {
  const fs::path dir = test::fresh_temp_dir("kill_" + name);
  auto manifest = testing::create_sim_session(dir, small_sim_config(), scheme, bracket);
  EXPECT_TRUE(manifest) << manifest.error().describe();
  return dir;
}

/// What a resumed `vdrig capture --resume DIR` does: rig from the manifest, capture the rest.
Status resume(const fs::path& dir, Session::WriteHook hook = {}) {
  auto session = Session::open(dir);
  if (!session) return session.error();
  session->set_write_hook(std::move(hook));
  auto rig = make_sim_rig(session->manifest().rig_config);
  if (!rig) return rig.error();
  CaptureOptions o;
  o.bracket = parse_bracket(session->manifest().bracket).value();
  o.disk_reserve_bytes = 0;
  return run_session(rig.value(), session.value(), o);
}

/// Checks the journal line by line: each planned view complete exactly once, with `bracket` frames that decode.
void expect_complete_exactly_once(const fs::path& dir, int bracket) {
  auto session = Session::open(dir);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  std::vector<int> completions(n, 0);
  std::ifstream in(SessionLayout(dir).journal_file());
  std::string line;
  while (std::getline(in, line)) {
    const json j = json::parse(line, nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << line;
    if (j.value("type", "") == "view_complete") {
      const int v = j.at("view").get<int>();
      ASSERT_TRUE(v >= 0 && v < n);
      ++completions[v];
      EXPECT_EQ(j.at("frames").get<int>(), bracket);
    }
  }
  for (int v = 0; v < n; ++v) {
    EXPECT_EQ(completions[v], 1) << "view " << v;
    const auto frames = session->frames_of_view(v);
    ASSERT_EQ(static_cast<int>(frames.size()), bracket) << "view " << v;
    for (const auto& f : frames) {
      auto image = session->load_image(f);
      ASSERT_TRUE(image) << f.file << ": " << image.error().describe();
      EXPECT_EQ(image->cols, 160);
      EXPECT_EQ(image->rows, 120);
    }
  }
}

TEST(CaptureKill, SigkillAtRandomMomentsLosesNothing) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path dir = create_session("sigkill", "spiral:150:7@80", "fixed:0.5,0.125");
  ASSERT_EQ(Session::open(dir)->manifest().views.size(), 150u);
  // A kill moment: once the journal has grown by a random number of bytes (so every round interrupts real work
  // whatever the machine's speed), plus a random 0..15 ms so the kill lands anywhere in the next view's work: its
  // frame writes, its fsyncs, or its commit (the journal grows only at commits).
  std::mt19937 rng(12345);
  std::uniform_int_distribution<std::uintmax_t> grow_bytes(1, 3000);
  std::uniform_int_distribution<int> extra_us(0, 15000);
  int killed_mid_run = 0;
  for (int round = 0; round < 20; ++round) {
    const std::uintmax_t start_size = fs::file_size(SessionLayout(dir).journal_file());
    const std::uintmax_t target = start_size + grow_bytes(rng);
    const auto status = test::kill_when_grown([&] { return resume(dir); }, SessionLayout(dir).journal_file(), target,
                                              [&] { return extra_us(rng); }, std::chrono::seconds(10));
    ASSERT_TRUE(status) << "fork failed";
    if (WIFSIGNALED(*status))
      ++killed_mid_run;
    else
      ASSERT_EQ(WEXITSTATUS(*status), 0) << "child failed before the kill";
  }
  auto partial = Session::open(dir);
  ASSERT_TRUE(partial) << partial.error().describe();
  const int done_before_final = partial->completed_view_count();
  ASSERT_TRUE(resume(dir));
  expect_complete_exactly_once(dir, 2);
  // The kills must have interrupted real work, or the test proves nothing.
  EXPECT_GE(killed_mid_run, 15);
  EXPECT_GT(done_before_final, 0);
  EXPECT_LT(done_before_final, 150);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(seconds, 60.0);
  std::printf("kill test: %d kills mid-run, %d/150 views done before the final resume, %.1f s\n", killed_mid_run,
              done_before_final, seconds);
  fs::remove_all(dir);
}

TEST(CaptureKill, FullDiskStopsWithNoSpaceAndResumes) {
  const fs::path dir = create_session("nospace", "spiral:40:3@80", "fixed:0.5,0.125");
  // The disk "fills up" at the 33rd write. A view of 2 frames is 3 writes (its two images, then one journal append
  // committing its frame lines and its completion), so 10 views complete and the 11th is cut at its commit.
  int writes = 0;
  const Status s = resume(dir, [&](const fs::path& p) -> Status {
    if (++writes > 32) return make_error(ErrorCode::kNoSpace, "injected: no space left writing " + p.string());
    return Status::ok();
  });
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kNoSpace);
  auto stopped = Session::open(dir);
  ASSERT_TRUE(stopped);
  EXPECT_EQ(stopped->completed_view_count(), 10);
  EXPECT_FALSE(stopped->view_complete(10));
  // Its image files were written, but without a durable commit they do not count: not one of its frames is journaled.
  EXPECT_TRUE(fs::exists(SessionLayout(dir).frame_file(10, 0)));
  EXPECT_TRUE(fs::exists(SessionLayout(dir).frame_file(10, 1)));
  EXPECT_EQ(stopped->frames_of_view(10).size(), 0u);
  EXPECT_EQ(stopped->frames().size(), 20u);
  // A reserve larger than the free space: stops before the first view, nothing written.
  {
    auto session = Session::open(dir);
    auto rig = make_sim_rig(session->manifest().rig_config);
    CaptureOptions o;
    o.exposures_s = {0.5, 0.125};
    o.disk_reserve_bytes = free_disk_bytes(dir).value() + (1ull << 30);
    const Status r = run_capture(rig.value(), session.value(), o);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code, ErrorCode::kNoSpace);
    EXPECT_EQ(Session::open(dir)->frames().size(), session->frames().size());
  }
  ASSERT_TRUE(resume(dir));
  expect_complete_exactly_once(dir, 2);
  fs::remove_all(dir);
}

// A stalled axis (a drive alarm that outlasts the retries) ends the capture, and the axes stay where they are: before,
// the capture "parked" by moving to (0, 0), i.e. drove whichever axis still answered into a jammed rig.
TEST(StageFault, TheAxesAreNotParkedAfterAStageFault) {
  const fs::path dir = create_session("stall", "latlong:2", "fixed:0.01");
  auto session = Session::open(dir);
  ASSERT_TRUE(session) << session.error().describe();
  json config = small_sim_config();
  // Moves 1 and 2 reach views 0 and 1; move 3 (view 2) fails on every one of its 4 attempts; a park would be move 7.
  config["sim"]["faults"] = {{"drive_error_at", {3, 4, 5, 6}}};
  auto rig = make_sim_rig(config);
  ASSERT_TRUE(rig) << rig.error().describe();
  CaptureOptions o;
  o.bracket = parse_bracket("fixed:0.01").value();
  o.disk_reserve_bytes = 0;
  o.retry.initial_backoff_s = 0.001;
  const Status s = run_session(rig.value(), session.value(), o);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDevice) << s.describe();
  const auto at = rig->stage->position();
  ASSERT_TRUE(at) << at.error().describe();
  const PanTilt view1 = session->manifest().views[1].target;
  EXPECT_NEAR(at->pan_rad, view1.pan_rad, 1e-9) << "the stage was parked";
  EXPECT_NEAR(at->tilt_rad, view1.tilt_rad, 1e-9) << "the stage was parked";
  EXPECT_GT(std::abs(at->tilt_rad) + std::abs(at->pan_rad), 1e-3) << "view 1 is not at (0, 0)";
}

}  // namespace
}  // namespace vdrig::capture

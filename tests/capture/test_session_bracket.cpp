// Exposure brackets (parse/validate and the auto search) and fault handling of run_capture, on exact fake devices.
#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "fake_rig.hpp"
#include "test_support.hpp"
#include "vdrig/capture/bracket.hpp"
#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/plan.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using testing::FakeCamera;
using testing::FakeStage;

Manifest small_manifest(const std::string& bracket, int views) {
  Manifest m;
  m.scheme = "test";
  m.bracket = bracket;
  for (int i = 0; i < views; ++i) m.views.push_back({i, Vec3d::UnitZ(), PanTilt{0.1 * i, 0.05 * i}});
  return m;
}

TEST(BracketSpec, ParsesFixedAndRejectsBadOnes) {
  auto b = parse_bracket("fixed:0.5,0.125,0.03125");
  ASSERT_TRUE(b) << b.error().describe();
  EXPECT_EQ(b->kind, BracketSpec::Kind::kFixed);
  ASSERT_EQ(b->exposures_s.size(), 3u);
  EXPECT_DOUBLE_EQ(b->exposures_s[1], 0.125);
  EXPECT_EQ(b->max_frames(), 3);

  auto dup = parse_bracket("fixed:0.5,0.25,0.5");
  ASSERT_FALSE(dup);
  EXPECT_NE(dup.error().message.find("duplicate"), std::string::npos) << dup.error().message;
  auto neg = parse_bracket("fixed:0.5,-0.1");
  ASSERT_FALSE(neg);
  EXPECT_NE(neg.error().message.find("positive"), std::string::npos) << neg.error().message;
  EXPECT_FALSE(parse_bracket("fixed:0"));
  EXPECT_FALSE(parse_bracket("fixed:"));
  EXPECT_FALSE(parse_bracket("fixed:0.1,,0.2"));
  EXPECT_FALSE(parse_bracket("fixed:abc"));
  EXPECT_FALSE(parse_bracket("fixed:nan"));
  EXPECT_FALSE(parse_bracket("fixed:inf"));
  EXPECT_FALSE(parse_bracket("hdr"));
  EXPECT_EQ(parse_bracket("bogus").error().code, ErrorCode::kInvalidArgument);
}

TEST(BracketSpec, ParsesAutoWithLimitsAndRoi) {
  auto a = parse_bracket("auto");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->kind, BracketSpec::Kind::kAuto);
  EXPECT_DOUBLE_EQ(a->ceiling_s, 1.0);
  auto b = parse_bracket("auto:2:0.25@1,2,30,40");
  ASSERT_TRUE(b) << b.error().describe();
  EXPECT_DOUBLE_EQ(b->ceiling_s, 2.0);
  EXPECT_DOUBLE_EQ(b->floor_s, 0.25);
  ASSERT_TRUE(b->roi);
  EXPECT_EQ(b->roi->width, 30);
  EXPECT_EQ(b->max_frames(), 4);  // 2, 1, 0.5, 0.25
  auto round = parse_bracket(b->to_spec());
  ASSERT_TRUE(round);
  EXPECT_DOUBLE_EQ(round->floor_s, 0.25);
  EXPECT_EQ(round->roi->height, 40);
  EXPECT_FALSE(parse_bracket("auto:0.1:1"));  // floor above ceiling
  EXPECT_FALSE(parse_bracket("auto:-1"));
  EXPECT_FALSE(parse_bracket("auto@1,2,0,4"));  // empty ROI
  EXPECT_FALSE(parse_bracket("auto@1,2,3"));
  EXPECT_FALSE(parse_bracket("auto:1:0.5:0.1"));
}

TEST(AutoBracket, HalvesUntilNothingSaturatedAndRecordsEveryFrame) {
  const test::TempDir dir("bracket_auto");
  auto session = Session::create(dir, small_manifest("auto", 3));
  ASSERT_TRUE(session);
  FakeStage* stage = nullptr;
  FakeCamera* camera = nullptr;
  rig::Rig rig = testing::make_fake_rig(&stage, &camera);
  camera->bright = 1000;  // saturates (>= 255) while exposure > 0.255 s
  CaptureOptions o;
  o.bracket = parse_bracket("auto:1:0.01").value();
  o.disk_reserve_bytes = 0;
  ASSERT_TRUE(run_capture(rig, session.value(), o));
  const std::vector<double> expected = {1.0, 0.5, 0.25};  // 0.25 * 1000 = 250 < 255: first unsaturated
  for (int v = 0; v < 3; ++v) {
    EXPECT_TRUE(session->view_complete(v));
    const auto frames = session->frames_of_view(v);
    ASSERT_EQ(frames.size(), expected.size());
    for (size_t k = 0; k < frames.size(); ++k) {
      EXPECT_DOUBLE_EQ(frames[k].exposure_s, expected[k]);
      EXPECT_EQ(frames[k].saturated, k + 1 < expected.size());
    }
  }
  // Reopened from disk, the same.
  auto again = Session::open(dir);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->view_frame_count(2), 3);
}

TEST(AutoBracket, RegionOfInterestAndFloor) {
  const test::TempDir dir("bracket_roi");
  auto session = Session::create(dir, small_manifest("auto", 2));
  ASSERT_TRUE(session);
  FakeCamera* camera = nullptr;
  rig::Rig rig = testing::make_fake_rig(nullptr, &camera);
  camera->dim = 100;     // never saturates in [0, 1] s
  camera->bright = 1e6;  // saturates down to 0.255 ms
  CaptureOptions o;
  o.disk_reserve_bytes = 0;
  o.bracket = parse_bracket("auto:1:0.1@10,10,10,10").value();  // ROI avoids the hot corner: one frame
  ASSERT_TRUE(run_capture(rig, session.value(), o));
  EXPECT_EQ(session->frames_of_view(0).size(), 1u);
  EXPECT_FALSE(session->frames_of_view(0)[0].saturated);

  const test::TempDir dir2("bracket_floor");
  auto s2 = Session::create(dir2, small_manifest("auto", 1));
  ASSERT_TRUE(s2);
  o.bracket = parse_bracket("auto:1:0.1").value();  // whole image: stops at the floor, still saturated
  ASSERT_TRUE(run_capture(rig, s2.value(), o));
  const auto frames = s2->frames_of_view(0);
  ASSERT_EQ(frames.size(), 4u);  // 1, 0.5, 0.25, 0.125 (0.0625 < floor)
  EXPECT_DOUBLE_EQ(frames.back().exposure_s, 0.125);
  EXPECT_TRUE(frames.back().saturated);
}

TEST(Capture, WarnsInJournalWhenCameraIsInAutoExposure) {
  const test::TempDir dir("bracket_autoexp");
  auto session = Session::create(dir, small_manifest("fixed:0.1", 1));
  ASSERT_TRUE(session);
  FakeCamera* camera = nullptr;
  rig::Rig rig = testing::make_fake_rig(nullptr, &camera);
  camera->auto_exposure = true;
  CaptureOptions o;
  o.exposures_s = {0.1};
  o.disk_reserve_bytes = 0;
  ASSERT_TRUE(run_capture(rig, session.value(), o));
  std::ifstream in(SessionLayout(dir).journal_file());
  std::string text((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(text.find("auto exposure"), std::string::npos) << text;
}

TEST(Capture, RetriesTransientFaultsThenStopsWithTheFault) {
  const test::TempDir dir("bracket_faults");
  auto session = Session::create(dir, small_manifest("fixed:0.1,0.2", 4));
  ASSERT_TRUE(session);
  FakeStage* stage = nullptr;
  FakeCamera* camera = nullptr;
  rig::Rig rig = testing::make_fake_rig(&stage, &camera);
  CaptureOptions o;
  o.exposures_s = {0.1, 0.2};
  o.disk_reserve_bytes = 0;
  o.retry = {3, 0.001, 0.01};
  camera->fail_captures = 2;  // two faults, third attempt works
  stage->fail_moves = 2;
  std::atomic<bool> stop{false};
  int frames_seen = 0;
  o.stop_requested = &stop;
  o.on_progress = [&](const CaptureProgress& p) {
    if (!p.view_finished && ++frames_seen == 3) {
      // From the 4th capture on the camera fails more often than the retries allow.
      camera->fail_captures = 1000;
    }
  };
  const Status s = run_capture(rig, session.value(), o);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_TRUE(session->view_complete(0));
  EXPECT_FALSE(session->view_complete(1));           // one frame of view 1 taken, the view is not done
  EXPECT_EQ(session->frames_of_view(1).size(), 0u);  // frames count only with their view's commit
  EXPECT_EQ(camera->attempts, 2 + 3 + 3);            // 2 faults + 3 good, then 3 failing attempts

  camera->fail_captures = 0;
  auto reopened = Session::open(dir);
  ASSERT_TRUE(reopened);
  EXPECT_FALSE(reopened->view_complete(1));
  o.on_progress = nullptr;
  ASSERT_TRUE(run_capture(rig, reopened.value(), o));
  for (int v = 0; v < 4; ++v) EXPECT_EQ(reopened->frames_of_view(v).size(), 2u);
  EXPECT_EQ(reopened->completed_view_count(), 4);
}

TEST(Capture, DiskReserveStopsBeforeAnythingIsWritten) {
  const test::TempDir dir("bracket_reserve");
  auto session = Session::create(dir, small_manifest("fixed:0.1", 2));
  ASSERT_TRUE(session);
  rig::Rig rig = testing::make_fake_rig();
  auto free_bytes = free_disk_bytes(dir);
  ASSERT_TRUE(free_bytes);
  CaptureOptions o;
  o.exposures_s = {0.1};
  o.disk_reserve_bytes = free_bytes.value() + (1ull << 30);
  const Status s = run_capture(rig, session.value(), o);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().code, ErrorCode::kNoSpace);
  EXPECT_TRUE(session->frames().empty());
  o.disk_reserve_bytes = 0;
  ASSERT_TRUE(run_capture(rig, session.value(), o));
  EXPECT_EQ(session->completed_view_count(), 2);
}

TEST(Session, TornJournalLineIsCutSoLaterAppendsStayReadable) {
  const test::TempDir dir("bracket_torn");
  auto session = Session::create(dir, small_manifest("fixed:0.1", 3));
  ASSERT_TRUE(session);
  rig::Rig rig = testing::make_fake_rig();
  CaptureOptions o;
  o.exposures_s = {0.1};
  o.disk_reserve_bytes = 0;
  ASSERT_TRUE(session->mark_view_complete(0, 0));
  {
    std::ofstream out(SessionLayout(dir).journal_file(), std::ios::app);
    out << R"({"type":"frame","view":1,"bra)";  // a crash mid-append
  }
  auto reopened = Session::open(dir);
  ASSERT_TRUE(reopened) << reopened.error().describe();
  ASSERT_TRUE(run_capture(rig, reopened.value(), o));
  auto final_open = Session::open(dir);
  ASSERT_TRUE(final_open) << final_open.error().describe();
  EXPECT_EQ(final_open->completed_view_count(), 3);
}

TEST(Plan, RoutePlannerOrdersViewsAndRecordsTimes) {
  FakeStage stage;
  PlanRequest req;
  req.scheme = "latlong:4";
  req.bracket = "fixed:0.1";
  req.stage = stage.spec();
  auto m = plan_manifest(req);
  ASSERT_TRUE(m) << m.error().describe();
  const auto& route = m->extra.at("route");
  EXPECT_LE(route.at("planned_time_s").get<double>(), route.at("naive_time_s").get<double>() + 1e-9);
  EXPECT_GT(route.at("naive_time_s").get<double>(), 0);
  // Every scheme direction is planned exactly once.
  auto idx = route.at("scheme_index").get<std::vector<size_t>>();
  std::sort(idx.begin(), idx.end());
  for (size_t k = 0; k < idx.size(); ++k) EXPECT_EQ(idx[k], k);
  EXPECT_EQ(idx.size(), m->views.size());
  req.bracket = "fixed:0.1,0.1";
  EXPECT_FALSE(plan_manifest(req));
}

}  // namespace
}  // namespace vdrig::capture

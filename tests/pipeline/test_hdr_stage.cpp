// merge_session_hdr says what it did: a first run merges every view, a second finds them all current and merges none
// (`vdrig hdr` printed "merged 73 views" for a run that merged nothing), a damaged HDR image is merged again, and
// progress reaches every view of the session.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

TEST(HdrStage, CountsMergedAndCurrentViewsAndReportsProgress) {
  vdrig::test::TempDir root("hdr_counts");
  CaptureRequest req;
  req.out_dir = root.path() / "S";
  req.rig_config = sim::sim_rig_config({{"scene", "patchwork"}, {"camera", {{"width", 96}, {"height", 72}}}});
  req.scheme = "latlong:2";
  req.exposures_s = {1.0, 0.25};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n, 3);

  int calls = 0, last_done = 0, last_total = 0;
  HdrMergeOptions options;
  options.on_view = [&](int done, int total) {
    EXPECT_EQ(done, last_done + 1) << "progress goes up one view at a time";
    ++calls, last_done = done, last_total = total;
  };
  auto first = merge_session_hdr(session.value(), options);
  ASSERT_TRUE(first) << first.error().describe();
  EXPECT_EQ(first->merged, n);
  EXPECT_EQ(first->current, 0);
  EXPECT_EQ(first->incomplete, 0);
  EXPECT_EQ(calls, n);
  EXPECT_EQ(last_done, n);
  EXPECT_EQ(last_total, n);

  auto again = merge_session_hdr(session.value());
  ASSERT_TRUE(again) << again.error().describe();
  EXPECT_EQ(again->merged, 0) << "nothing to merge: every view is current";
  EXPECT_EQ(again->current, n);

  // A damaged HDR image is merged again (and counted so); the others stay current.
  { std::ofstream(session->layout().hdr_file(1), std::ios::trunc) << "not an EXR"; }
  auto repaired = merge_session_hdr(session.value());
  ASSERT_TRUE(repaired) << repaired.error().describe();
  EXPECT_EQ(repaired->merged, 1);
  EXPECT_EQ(repaired->current, n - 1);

  HdrMergeOptions force;
  force.force = true;
  auto forced = merge_session_hdr(session.value(), force);
  ASSERT_TRUE(forced) << forced.error().describe();
  EXPECT_EQ(forced->merged, n);
  EXPECT_EQ(forced->current, 0);
}

}  // namespace
}  // namespace vdrig::pipeline

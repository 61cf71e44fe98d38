// merge_session_hdr says what it did: a first run merges every view, a second finds them all current and merges none
// (`vdrig hdr` printed "merged 73 views" for a run that merged nothing), a damaged HDR image is merged again, and
// progress reaches every view of the session.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"

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
  ASSERT_TRUE(vdrig::test::write_true_calibration(session.value()));  // not a calibration test: the true response

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

// The response curve comes from the session's own brackets (`vdrig calib response SESSION`), never from the
// simulator's configuration: without calib/response.json the merge stops and names the command; the recovered curve
// follows the true one up to the scale a bracket cannot see.
TEST(HdrStage, ResponseIsRecoveredFromTheSessionsBracketsNotTakenFromTheSimulator) {
  vdrig::test::TempDir root("hdr_response");
  CaptureRequest req;
  req.out_dir = root.path() / "S";
  req.rig_config = sim::sim_rig_config({{"scene", "patchwork"}, {"camera", {{"width", 160}, {"height", 120}}}});
  req.scheme = "latlong:2";
  req.exposures_s = {1.0, 0.25, 0.0625};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();

  const auto missing = merge_session_hdr(session.value());
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("vdrig calib response"), std::string::npos) << missing.error().message;

  auto cal = calibrate_session_response(session.value());
  ASSERT_TRUE(cal) << cal.error().describe();
  EXPECT_TRUE(fs::exists(session->layout().response_file()));
  auto response = session_response(session.value());
  ASSERT_TRUE(response) << response.error().describe();
  auto truth = ground_truth_of(req.rig_config);
  ASSERT_TRUE(truth && truth->has_value());
  const ResponseCurve& want = (*truth)->response;
  // Relative to the mid code (the scale is free): the worst departure over codes 10 %..90 % of the range.
  const double mid = want.max_code() / 2.0;
  double worst = 0;
  for (int c = 0; c < 3; ++c)
    for (double z = 0.1 * want.max_code(); z <= 0.9 * want.max_code(); z += 1.0) {
      const double got_rel = response->inverse(c, z) / response->inverse(c, mid);
      const double want_rel = want.inverse(c, z) / want.inverse(c, mid);
      worst = std::max(worst, std::abs(got_rel / want_rel - 1.0));
    }
  std::printf("response from view %d (%d codes covered): worst relative departure %.4f over codes 10-90 %%\n",
              cal->view, cal->codes_covered, worst);
  EXPECT_LT(worst, 0.09);  // measured 0.058 (160x120, view 12 of latlong:2, 3 exposures)
  ASSERT_TRUE(merge_session_hdr(session.value()));
}

}  // namespace
}  // namespace vdrig::pipeline

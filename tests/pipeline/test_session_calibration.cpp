// The camera's intrinsics from a session of the built-in chessboard scene (`vdrig calib intrinsics --session`), as
// the demo calibrates them: recovered from the images alone, against the simulator's true camera.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

TEST(SessionCalibration, IntrinsicsFromAChessboardSessionMatchTheSimulatedCamera) {
  const test::TempDir dir("chessboard");
  CaptureRequest req;
  req.out_dir = dir / "chessboard";
  req.rig_config = sim::sim_rig_config({{"scene", "chessboard"}});
  req.scheme = "latlong:4:65";
  req.exposures_s = {1.0, 0.25};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();

  // Extrinsics want a camera model: none given and none in calib/ is an error naming the command that makes one.
  const auto no_camera = calibrate_session_geometry(session.value());
  ASSERT_FALSE(no_camera);
  EXPECT_EQ(no_camera.error().code, ErrorCode::kNotFound);
  EXPECT_NE(no_camera.error().message.find("vdrig calib intrinsics"), std::string::npos) << no_camera.error().message;

  SessionIntrinsicsOptions options;  // the chessboard scene's 8 x 6 inner corners of 160 mm are the defaults
  options.intrinsics.fix_k3 = true;
  auto result = calibrate_session_intrinsics(session.value(), options);
  ASSERT_TRUE(result) << result.error().describe();
  const auto truth = ground_truth_of(req.rig_config);
  ASSERT_TRUE(truth && truth->has_value());
  const CameraModel& want = (*truth)->camera;
  const CameraModel& got = result->camera;
  std::printf(
      "chessboard: %zu of %zu views used, RMS %.3f px; fx %.2f fy %.2f cx %.2f cy %.2f k1 %.4f k2 %.4f k3 %.4f "
      "(truth fx %.1f fy %.1f cx %.1f cy %.1f k1 %.3f k2 %.3f)\n",
      result->used_views(), result->views.size(), result->rms_px, got.fx, got.fy, got.cx, got.cy, got.k1, got.k2,
      got.k3, want.fx, want.fy, want.cx, want.cy, want.k1, want.k2);
  EXPECT_EQ(got.width, want.width);
  EXPECT_EQ(got.height, want.height);
  // Measured: 56 of 56 views, RMS 0.159 px, fx 799.22, fy 798.98, cx 319.50, cy 239.46, k1 -0.0748 (k2 takes up
  // the rest of the true k1 -0.08, k2 0.02 over the image); bounds about 1.5 times the departures.
  EXPECT_GE(result->used_views(), 40u);
  EXPECT_LT(result->rms_px, 0.24);
  EXPECT_NEAR(got.fx, want.fx, 1.6);
  EXPECT_NEAR(got.fy, want.fy, 1.6);
  EXPECT_NEAR(got.cx, want.cx, 1.0);
  EXPECT_NEAR(got.cy, want.cy, 1.0);
  EXPECT_NEAR(got.k1, want.k1, 0.008);
  EXPECT_EQ(got.k3, 0.0) << "held at 0 (fix_k3)";
}

}  // namespace
}  // namespace vdrig::pipeline

// What `vdrig probe animate` needs besides the frames themselves, as library calls: the default camera framing a
// path (animation.hpp, frame_path) and the ffmpeg hand-off (video.hpp).
#include <gtest/gtest.h>

#include <vector>

#include "vdrig/probe/animation.hpp"
#include "vdrig/probe/video.hpp"

namespace vdrig::probe {
namespace {

TEST(FramePath, EveryPositionAndSphereIsInView) {
  const std::vector<Vec3d> path = {Vec3d(-800, -200, 400), Vec3d(0, 300, 600), Vec3d(900, 100, 300)};
  const double radius = 150;
  SceneCamera c = frame_path(path, radius, 50);
  std::string why;
  ASSERT_TRUE(c.is_valid(&why)) << why;
  EXPECT_LT(c.position_mm.y(), c.look_at_mm.y()) << "seen from the -y side";
  EXPECT_GT(c.position_mm.z(), c.look_at_mm.z()) << "from above";
  for (const Vec3d& p : path)
    for (const Vec3d& edge : {Vec3d(p.x() - radius, p.y(), p.z()), Vec3d(p.x() + radius, p.y(), p.z())}) {
      double x = 0, y = 0;
      ASSERT_TRUE(c.project(edge, &x, &y));
      EXPECT_GE(x, 0);
      EXPECT_LT(x, c.width);
      EXPECT_GE(y, 0);
      EXPECT_LT(y, c.height);
    }
  // A wider field of view brings the camera closer.
  const SceneCamera wide = frame_path(path, radius, 80);
  EXPECT_LT((wide.position_mm - wide.look_at_mm).norm(), (c.position_mm - c.look_at_mm).norm());
}

TEST(Video, ProgramsOnPathAndTheirExitStatus) {
  EXPECT_FALSE(find_on_path("sh").empty());
  EXPECT_TRUE(find_on_path("vdrig-no-such-program").empty());
  EXPECT_EQ(run_program({find_on_path("sh").string(), "-c", "exit 3"}), 3);
  EXPECT_EQ(run_program({"/nonexistent/program"}), -1) << "cannot start";
  EXPECT_EQ(encode_frames_mp4(".", 0).error().code, ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace vdrig::probe

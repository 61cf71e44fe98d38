// The files of a session folder: SessionLayout spells each name once, and Session writes where it says. The names
// are a contract with sessions already on disk, so this test spells them out.
#include <gtest/gtest.h>

#include "test_support.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/capture/session_layout.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;

TEST(SessionLayout, NamesEveryFileOfTheSession) {
  const SessionLayout layout("/data/S");
  EXPECT_EQ(layout.dir(), fs::path("/data/S"));
  EXPECT_EQ(layout.manifest_file(), fs::path("/data/S/manifest.json"));
  EXPECT_EQ(layout.journal_file(), fs::path("/data/S/journal.jsonl"));
  EXPECT_EQ(layout.frames_dir(), fs::path("/data/S/frames"));
  EXPECT_EQ(SessionLayout::frame_file_relative(10, 1), fs::path("frames/view_0010_e01.png"));
  EXPECT_EQ(layout.frame_file(10, 1), fs::path("/data/S/frames/view_0010_e01.png"));
  EXPECT_EQ(layout.frame_file(12345, 123), fs::path("/data/S/frames/view_12345_e123.png"));
  EXPECT_EQ(layout.hdr_dir(), fs::path("/data/S/hdr"));
  EXPECT_EQ(layout.hdr_file(7), fs::path("/data/S/hdr/view_0007.exr"));
  EXPECT_EQ(layout.calib_dir(), fs::path("/data/S/calib"));
  EXPECT_EQ(layout.response_file(), fs::path("/data/S/calib/response.json"));
  EXPECT_EQ(layout.camera_file(), fs::path("/data/S/calib/camera.yml"));
  EXPECT_EQ(layout.views_file(), fs::path("/data/S/calib/views.json"));
  EXPECT_EQ(layout.obsmap_dir(), fs::path("/data/S/obsmap"));
  EXPECT_EQ(layout.obsmap_file(512, 256), fs::path("/data/S/obsmap/512x256.vdobs"));
  EXPECT_EQ(layout.maps_dir(), fs::path("/data/S/maps"));
  EXPECT_EQ(layout.parameter_map_file("phong:1"), fs::path("/data/S/maps/phong:1.exr"));
  EXPECT_EQ(layout.parameter_map_file("phong:auto"), fs::path("/data/S/maps/phong:auto.exr"));
  EXPECT_EQ(layout.renders_dir(), fs::path("/data/S/renders"));
}

TEST(SessionLayoutDeathTest, AModelSpecMustBeAPlainFileName) {
  const SessionLayout layout("/data/S");
  EXPECT_DEATH((void)layout.parameter_map_file("../escape"), "model spec");
  EXPECT_DEATH((void)layout.parameter_map_file(""), "model spec");
}

TEST(SessionLayout, SessionWritesWhereTheLayoutSays) {
  const vdrig::test::TempDir dir("layout");
  Manifest manifest;
  manifest.scheme = "test";
  manifest.bracket = "fixed:0.1";
  manifest.views.push_back({0, Vec3d::UnitZ(), PanTilt{}});
  auto session = Session::create(dir.path(), manifest);
  ASSERT_TRUE(session) << session.error().describe();
  const SessionLayout layout = session->layout();
  EXPECT_EQ(layout.dir(), dir.path());
  EXPECT_TRUE(fs::is_regular_file(layout.manifest_file()));
  EXPECT_TRUE(fs::is_regular_file(layout.journal_file()));
  EXPECT_TRUE(fs::is_directory(layout.frames_dir()));

  Frame frame;
  frame.image = cv::Mat(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  frame.exposure_s = 0.1;
  auto record = session->append_frame(0, 0, frame, false);
  ASSERT_TRUE(record) << record.error().describe();
  EXPECT_EQ(fs::path(record->file), SessionLayout::frame_file_relative(0, 0));
  EXPECT_TRUE(fs::is_regular_file(layout.frame_file(0, 0)));
  ASSERT_TRUE(session->mark_view_complete(0, 1));
  EXPECT_GT(fs::file_size(layout.journal_file()), 0u);
}

}  // namespace
}  // namespace vdrig::capture

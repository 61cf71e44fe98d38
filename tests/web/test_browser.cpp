// The web console in a real browser: tests/web/browser/console_test.mjs drives Debian's headless chromium through
// the page served by this process's web server on vdrigd's simulated rig: a refused start shows the daemon's
// reason, a started session streams its progress, pauses (and then stays put), resumes and completes, the list
// follows, and nothing is logged as an error. Skips when chromium, node or the test's node_modules (scripts/setup:
// npm ci in tests/web/browser) are absent.
#include <gtest/gtest.h>

#include "vdrig/test/browser.hpp"
#include "vdrig/test/build_paths.hpp"
#include "web_support.hpp"

namespace vdrig::web::testing {
namespace {
using nlohmann::json;

TEST(WebBrowser, StartPauseResumeFromTheFormWithLiveProgress) {
  const std::string chromium = vdrig::test::find_chromium();
  const fs::path dir = fs::path(VDRIG_SOURCE_DIR) / "tests" / "web" / "browser";
  if (const std::string why = vdrig::test::node_browser_test_unavailable(dir); !why.empty()) GTEST_SKIP() << why;

  vdrig::test::TempDir root("web_browser");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  const std::string session = "b1", scheme = "spiral:40:2@80";
  const auto run = vdrig::test::run_process({"/usr/bin/node", (dir / "console_test.mjs").string(), c.server().url(),
                                             chromium, (root.path() / "profile").string(), session, scheme},
                                            {.timeout_s = 90});
  ASSERT_EQ(run.exit_code, 0) << run.out << "\n" << run.err;
  const std::string out = run.out.substr(0, run.out.find_last_not_of('\n') + 1);
  const std::string last_line = out.substr(out.rfind('\n') + 1);
  const json seen = json::parse(last_line, nullptr, false);
  ASSERT_FALSE(seen.is_discarded()) << run.out;
  std::cout << "browser saw: " << seen.dump() << "\n";

  EXPECT_EQ(seen.value("address", ""), "http://127.0.0.1:" + std::to_string(c.port()) + "/")
      << "the token stays in the address bar";
  const std::string refused = seen.value("startError", "");
  EXPECT_EQ(refused.rfind("invalid_argument: ", 0), 0u) << refused;
  EXPECT_NE(refused.find("nonsense"), std::string::npos) << "the daemon's reason names the scheme: " << refused;
  EXPECT_GE(seen.value("eventsWhileRunning", 0), 2) << "progress events pushed to the page";
  const int total = seen.value("total", 0);
  EXPECT_EQ(total, 40);
  EXPECT_LT(seen.value("pausedAt", 0), total) << "paused before the end";
  EXPECT_EQ(seen.value("stateAfterPause", ""), "paused");
  EXPECT_EQ(seen.value("progressAfterPause", -1), seen.value("pausedAt", -2)) << "no progress while paused";
  EXPECT_EQ(seen["final"], json::array({total, total}));
  EXPECT_EQ(seen.value("row", ""), std::to_string(total) + "/" + std::to_string(total));
  EXPECT_TRUE(seen["consoleErrors"].empty()) << seen["consoleErrors"].dump();

  // The live pieces. The hemisphere: every planned view drawn filled (a dot is ~30 green pixels).
  EXPECT_EQ(seen["hemisphere"].value("done", 0), total);
  EXPECT_EQ(seen["hemisphere"].value("views", 0), total);
  EXPECT_GE(seen["hemisphere"].value("greenPixels", 0), 15 * total) << seen["hemisphere"].dump();
  // The thumbnail: the last frame of the last view, at most 240 wide with the frame's aspect (160x120), not blank.
  const json& t = seen["thumbnail"];
  EXPECT_EQ(t.value("width", 0), 160) << t.dump();
  EXPECT_EQ(t.value("height", 0), 120) << t.dump();
  EXPECT_GE(t.value("view", -1), 0);
  EXPECT_EQ(t.value("bracket", -1), 1) << "the fixed bracket's second frame is the last";
  EXPECT_GT(t.value("max", 0.0) - t.value("min", 0.0), 20.0) << "a picture, not a flat fill: " << t.dump();
  EXPECT_GE(t.value("saturated", -1.0), 0.0);
  EXPECT_LE(t.value("saturated", 2.0), 1.0);
  EXPECT_NE(seen.value("thumbnailText", "").find("saturated"), std::string::npos) << seen.value("thumbnailText", "");
  // The journal's tail reaches the session's last view, and the drive line carries the measured position.
  const std::string log = seen.value("logTail", "");
  EXPECT_NE(log.find("view " + std::to_string(t.value("view", -1)) + " complete"), std::string::npos) << log;
  EXPECT_NE(log.find("frame 1: 0.0200 s"), std::string::npos) << log;
  EXPECT_NE(seen.value("drive", "").find("measured pan"), std::string::npos) << seen.value("drive", "");
  // Home and a 7.5 degree pan jog, as the daemon reports the stage's position.
  EXPECT_EQ(seen.value("homed", ""), "pan 0.00°, tilt 0.00°");
  EXPECT_EQ(seen.value("jogged", ""), "pan 7.50°, tilt 0.00°");
  EXPECT_LE(seen.value("expectedRefusals", 0), 1) << "the refused start's 400, logged by the browser";

  // What the page did, as the daemon has it: the session is complete.
  std::string buffer;
  const int fd = capture::testing::connect_unix(root.path() / "run" / "vdrigd.sock");
  ASSERT_GE(fd, 0);
  const json list = capture::testing::request(fd, buffer, {{"cmd", "list-sessions"}});
  ::close(fd);
  ASSERT_EQ(list["sessions"].size(), 1u) << list.dump() << ": the refused start left no session";
  EXPECT_EQ(list["sessions"][0].value("session", ""), session);
  EXPECT_EQ(list["sessions"][0].value("views_done", 0), total);
}

}  // namespace
}  // namespace vdrig::web::testing

// Adaptive sampling's loop (capture/adaptive.hpp) without the pipeline: a scripted planner (a fixed list of
// directions per batch and a scripted predicted error) drives vdrigd's session runner, which reports each batch in
// `status` and in "adaptive_batch" events (views chosen so far, predicted error, why it stopped); and without any
// planner registered, an adaptive start is refused as unsupported before a session folder is made.
#include <gtest/gtest.h>

#include <thread>

#include "sim_session.hpp"
#include "vdrig/capture/adaptive.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/schemes.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

/// Batch k: 3 directions of a spiral, errors 0.5, 0.3, 0.29, 0.29, ...: flat from the third batch on.
class ScriptedPlanner final : public ViewPlanner {
 public:
  Result<BatchPlan> plan_batch(const BatchRequest& req) override {
    BatchPlan plan;
    const auto spiral = spiral_directions(60, 5, 80 * kPi / 180);
    for (int i = 0; i < req.max_views && i < 3; ++i) plan.directions.push_back(spiral[(req.batch * 7 + i * 13) % 60]);
    plan.predicted_error = req.batch == 1 ? 0.5 : req.batch == 2 ? 0.3 : 0.29;
    plan.info = {{"scripted", true}};
    return plan;
  }
};

struct Daemonised {
  explicit Daemonised(const fs::path& root) {
    daemon = std::make_unique<Daemon>(testing::sim_daemon_config(root));
    EXPECT_TRUE(daemon->start());
    thread = std::thread([this] { loop = daemon->run(); });
  }
  ~Daemonised() {
    daemon->request_stop();
    thread.join();
  }
  std::unique_ptr<Daemon> daemon;
  std::thread thread;
  Status loop;
};

TEST(AdaptiveLoop, TheDaemonReportsBatchesAndWhyItStopped) {
  register_view_planner_factory([] { return std::make_unique<ScriptedPlanner>(); });
  const test::TempDir root("adaptive_daemon");
  Daemonised d(root.path());
  const int fd = testing::connect_unix(d.daemon->socket_path());
  ASSERT_GE(fd, 0);
  std::string buf;
  ASSERT_TRUE(testing::request(fd, buf, {{"cmd", "subscribe"}}).value("ok", false));
  const json started = testing::request(fd, buf,
                                        {{"cmd", "start"},
                                         {"session", "a"},
                                         {"scheme", "adaptive:30,base=latlong:1,patience=2,gain=0.05"},
                                         {"bracket", "fixed:0.5"}});
  ASSERT_TRUE(started.value("ok", false)) << started.dump();
  std::vector<json> batches;
  std::string final_state;
  for (int k = 0; k < 100000 && final_state.empty(); ++k) {
    auto line = testing::read_line(fd, buf);
    ASSERT_TRUE(line) << "event stream ended";
    const json ev = json::parse(*line);
    if (ev.value("event", "") == "adaptive_batch") batches.push_back(ev);
    if (ev.value("event", "") == "state" && ev["state"] != "running") final_state = ev["state"];
  }
  ASSERT_EQ(final_state, "completed");
  // Errors 0.5, 0.3, 0.29, 0.29: changes of 40 %, 3.3 %, 0 % -> two flat batches after the fourth: stop.
  ASSERT_EQ(batches.size(), 5u);  // four batches and the stop
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(batches[i]["batches"].get<int>(), static_cast<int>(i) + 1);
    EXPECT_EQ(batches[i]["views_chosen"].get<int>(), 3 * (static_cast<int>(i) + 1));
    EXPECT_FALSE(batches[i].contains("stopped"));
  }
  EXPECT_NEAR(batches[3]["predicted_error"].get<double>(), 0.29, 1e-12);
  ASSERT_TRUE(batches[4].contains("stopped"));
  EXPECT_NE(batches[4]["stopped"].get<std::string>().find("converged"), std::string::npos) << batches[4].dump();
  const json status = testing::request(fd, buf, {{"cmd", "status"}});
  ASSERT_TRUE(status.contains("adaptive")) << status.dump();
  EXPECT_EQ(status["adaptive"]["views_chosen"].get<int>(), 12);
  EXPECT_TRUE(status["adaptive"].contains("stopped"));
  auto session = Session::open(root.path() / "sessions" / "a");
  ASSERT_TRUE(session);
  EXPECT_EQ(session->completed_view_count(), static_cast<int>(session->manifest().views.size()));
  EXPECT_LE(session->manifest().views.size(), 30u);
  ::close(fd);
  register_view_planner_factory({});
}

TEST(AdaptiveLoop, WithoutAPlannerAnAdaptiveStartIsUnsupported) {
  register_view_planner_factory({});
  const test::TempDir root("adaptive_none");
  Daemonised d(root.path());
  const int fd = testing::connect_unix(d.daemon->socket_path());
  ASSERT_GE(fd, 0);
  std::string buf;
  const json refused = testing::request(fd, buf, {{"cmd", "start"}, {"session", "a"}, {"scheme", "adaptive:30"}});
  EXPECT_FALSE(refused.value("ok", true)) << refused.dump();
  EXPECT_EQ(refused.value("code", ""), "unsupported") << refused.dump();
  EXPECT_FALSE(fs::exists(root.path() / "sessions" / "a"));
  ::close(fd);
}

}  // namespace
}  // namespace vdrig::capture

// SIGTERM on the real vdrigd executable: a small simulated session is started over its socket, the daemon is sent
// SIGTERM mid-session, and it must exit 0 promptly with the session journal consistent (every completed view has
// its whole bracket journaled before its completion line, and those frames decode); a second vdrigd then resumes
// the session to completion.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <thread>

#include "test_support.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/test/build_paths.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using testing::read_line;
using testing::request;

constexpr int kViews = 60;
constexpr int kBracket = 2;

/// A vdrigd child process on a private runtime/sessions folder.
class Vdrigd {
 public:
  explicit Vdrigd(const fs::path& root) : root_(root) {}
  ~Vdrigd() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }

  /// Starts vdrigd and waits (up to 10 s) until its socket accepts a connection; returns that connection.
  int start() {
#ifdef VDRIG_VDRIGD_PATH
    const std::string exe = VDRIG_VDRIGD_PATH;
#else
    const std::string exe;
#endif
    const std::string runtime = (root_ / "run").string(), sessions = (root_ / "sessions").string();
    const std::string rig = (root_ / "rig.json").string();
    fs::create_directories(root_);
    {
      std::ofstream out(rig);
      out << testing::small_sim_config().dump(2);
    }
    pid_ = ::fork();
    if (pid_ == 0) {
      const char* argv[] = {exe.c_str(),      "--runtime-dir",  runtime.c_str(),
                            "--sessions-dir", sessions.c_str(), "--rig",
                            rig.c_str(),      "--reserve-mb",   "0",
                            "--log-level",    "warn",           nullptr};
      ::execv(exe.c_str(), const_cast<char* const*>(argv));
      ::_exit(127);
    }
    if (pid_ < 0) return -1;
    const auto deadline = Clock::now() + std::chrono::seconds(10);
    while (Clock::now() < deadline) {
      const int fd = testing::connect_unix(root_ / "run" / "vdrigd.sock");
      if (fd >= 0) return fd;
      if (::waitpid(pid_, &status_, WNOHANG) == pid_) {
        pid_ = -1;
        return -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

  /// Sends SIGTERM and waits for the exit; returns the seconds it took and sets `status`.
  double terminate(int* status) {
    const auto t0 = Clock::now();
    ::kill(pid_, SIGTERM);
    const auto deadline = t0 + std::chrono::seconds(20);
    while (Clock::now() < deadline) {
      if (::waitpid(pid_, status, WNOHANG) == pid_) {
        pid_ = -1;
        return std::chrono::duration<double>(Clock::now() - t0).count();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return 1e9;  // the destructor SIGKILLs it
  }

 private:
  fs::path root_;
  pid_t pid_ = -1;
  int status_ = 0;
};

/// Reads pushed events until `until` returns true for one (or the stream ends / 60 s pass); returns that event.
json wait_event(int fd, std::string& buf, const std::function<bool(const json&)>& until) {
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (Clock::now() < deadline) {
    const auto line = read_line(fd, buf, 10000);
    if (!line) return json{{"closed", true}};
    const json ev = json::parse(*line, nullptr, false);
    if (!ev.is_discarded() && until(ev)) return ev;
  }
  return json{{"timeout", true}};
}

/// The journal, line by line: every view_complete line comes after the frame lines of brackets 0..frames-1 of its
/// view (written by the same commit), no view completes twice, and every frame of a completed view decodes.
/// Returns the number of completed views.
int check_journal(const fs::path& dir) {
  auto session = Session::open(dir);
  EXPECT_TRUE(session) << session.error().describe();
  if (!session) return -1;
  std::ifstream in(SessionLayout(dir).journal_file());
  std::string line;
  std::map<int, std::set<int>> brackets_seen;  // view -> bracket indices journaled so far
  std::set<int> completed;
  while (std::getline(in, line)) {
    const json j = json::parse(line, nullptr, false);
    EXPECT_FALSE(j.is_discarded()) << "journal line is not JSON: " << line;
    if (j.is_discarded()) continue;
    const std::string type = j.value("type", "");
    if (type == "frame") {
      brackets_seen[j.at("view").get<int>()].insert(j.at("bracket").get<int>());
    } else if (type == "view_complete") {
      const int view = j.at("view").get<int>();
      EXPECT_TRUE(completed.insert(view).second) << "view " << view << " completed twice";
      EXPECT_EQ(j.value("frames", -1), kBracket) << line;
      for (int b = 0; b < kBracket; ++b)
        EXPECT_TRUE(brackets_seen[view].count(b)) << "view " << view << " complete without bracket " << b;
    }
  }
  EXPECT_EQ(static_cast<int>(completed.size()), session->completed_view_count());
  for (int view : completed) {
    const auto frames = session->frames_of_view(view);
    EXPECT_EQ(static_cast<int>(frames.size()), kBracket) << "view " << view;
    for (const auto& f : frames) {
      auto image = session->load_image(f);
      EXPECT_TRUE(image) << f.file << ": " << (image ? "" : image.error().describe());
      if (image) {
        EXPECT_EQ(image->cols, 160);
        EXPECT_EQ(image->rows, 120);
      }
    }
  }
  return static_cast<int>(completed.size());
}

TEST(Vdrigd, SigtermMidSessionExitsCleanlyAndTheSessionResumes) {
#ifndef VDRIG_VDRIGD_PATH
  GTEST_SKIP() << "vdrigd is not part of this build (VDRIG_VDRIGD_PATH undefined)";
#endif
  const test::TempDir root("vdrigd_sigterm");
  const fs::path session_dir = root.path() / "sessions" / "s";
  int views_at_term = 0;
  {
    Vdrigd daemon(root.path());
    const int fd = daemon.start();
    ASSERT_GE(fd, 0) << "vdrigd did not come up";
    std::string buf;
    ASSERT_TRUE(request(fd, buf, {{"cmd", "subscribe"}}).value("ok", false));
    const json started = request(fd, buf,
                                 {{"cmd", "start"},
                                  {"session", "s"},
                                  {"scheme", "spiral:" + std::to_string(kViews) + ":4@80"},
                                  {"bracket", "fixed:0.5,0.125"}});
    ASSERT_TRUE(started.value("ok", false)) << started.dump();
    ASSERT_EQ(started.value("views_total", 0), kViews);
    // Mid-session: a few views done, and SIGTERM lands between (or inside) the commits that follow.
    const json ev = wait_event(
        fd, buf, [](const json& e) { return e.value("event", "") == "progress" && e.value("views_done", 0) >= 3; });
    ASSERT_EQ(ev.value("event", ""), "progress") << ev.dump();
    int status = 0;
    const double seconds = daemon.terminate(&status);
    EXPECT_LT(seconds, 5.0) << "vdrigd took too long to stop";
    ASSERT_TRUE(WIFEXITED(status)) << "vdrigd did not exit normally (signal " << WTERMSIG(status) << ")";
    EXPECT_EQ(WEXITSTATUS(status), 0);
    // The daemon closed the connection and removed its socket on the way out.
    while (read_line(fd, buf, 2000)) {
    }
    ::close(fd);
    EXPECT_FALSE(fs::exists(root.path() / "run" / "vdrigd.sock"));
    std::printf("vdrigd stopped %.3f s after SIGTERM\n", seconds);
  }
  views_at_term = check_journal(session_dir);
  EXPECT_GE(views_at_term, 3);
  EXPECT_LT(views_at_term, kViews) << "the session finished before SIGTERM: the test proves nothing";
  {
    // The stop is recorded: the capture was cancelled, not failed.
    std::ifstream in(SessionLayout(session_dir).journal_file());
    std::string text((std::istreambuf_iterator<char>(in)), {});
    EXPECT_NE(text.find("\"event\":\"stopped\""), std::string::npos);
  }

  // A new daemon resumes the session and completes it.
  {
    Vdrigd daemon(root.path());
    const int fd = daemon.start();
    ASSERT_GE(fd, 0) << "vdrigd did not come up again";
    std::string buf;
    ASSERT_TRUE(request(fd, buf, {{"cmd", "subscribe"}}).value("ok", false));
    const json resumed = request(fd, buf, {{"cmd", "resume"}, {"session", "s"}});
    ASSERT_TRUE(resumed.value("ok", false)) << resumed.dump();
    const json done = wait_event(
        fd, buf, [](const json& e) { return e.value("event", "") == "state" && e.value("state", "") != "running"; });
    EXPECT_EQ(done.value("state", ""), "completed") << done.dump();
    int status = 0;
    EXPECT_LT(daemon.terminate(&status), 5.0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    ::close(fd);
  }
  EXPECT_EQ(check_journal(session_dir), kViews);
}

}  // namespace
}  // namespace vdrig::capture

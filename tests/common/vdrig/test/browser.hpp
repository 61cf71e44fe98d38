// Loading a page in a real browser from a test: Debian's headless Chromium, the page served over HTTP on loopback by
// Python's http.server (pages from file:// cannot fetch(), which web viewers such as OpenLIME use), and the page's
// answer read back from the DOM that --dump-dom prints: the page writes JSON into <pre id="vdrig-result">.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "vdrig/test/process.hpp"

namespace vdrig::test {

/// Debian's chromium, or empty when not installed (scripts/setup installs it).
inline std::string find_chromium() {
  for (const char* candidate : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (::access(candidate, X_OK) == 0) return candidate;
  return "";
}

/// `python3 -m http.server` on 127.0.0.1 at a port it picks, serving `root`, for the lifetime of the object.
class LoopbackHttpServer {
 public:
  explicit LoopbackHttpServer(const std::filesystem::path& root) {
    if (::access("/usr/bin/python3", X_OK) != 0) return;
    log_ = root.string() + ".http.log";
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setpgid(0, 0);
      const int out = ::open(log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(out, 1);
      ::dup2(out, 2);
      const std::string dir = root.string();
      ::execl("/usr/bin/python3", "python3", "-u", "-m", "http.server", "0", "--bind", "127.0.0.1", "--directory",
              dir.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    // "Serving HTTP on 127.0.0.1 port 40123 (http://127.0.0.1:40123/) ..." once it listens.
    // (No std::regex: GCC 12's trips ASan in the sanitizer build.)
    for (int i = 0; i < 500 && port_ == 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      const std::string s = log();
      const auto at = s.find(" port ");
      if (at != std::string::npos) port_ = std::atoi(s.c_str() + at + 6);
    }
  }
  ~LoopbackHttpServer() {
    if (pid_ > 0) {
      ::kill(-pid_, SIGTERM);
      ::kill(pid_, SIGTERM);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
    std::error_code ignored;
    std::filesystem::remove(log_, ignored);
  }
  LoopbackHttpServer(const LoopbackHttpServer&) = delete;
  LoopbackHttpServer& operator=(const LoopbackHttpServer&) = delete;

  /// 0 when the server did not start (no python3, or it failed: log() says why).
  int port() const { return port_; }
  std::string url(const std::string& path) const { return "http://127.0.0.1:" + std::to_string(port_) + "/" + path; }
  std::string log() const {
    std::ifstream in(log_);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
  std::string log_;
};

/// What a page left in <pre id="vdrig-result"> (HTML entities decoded), chromium's console lines, or why not.
struct PageResult {
  bool ran = false;
  std::string result;
  std::string console_lines;  // chromium's log lines of console messages (any level)
  std::string failure;
};

/// Loads `url` in headless chromium with WebGL2 on SwiftShader (no GPU here) and `virtual_time_ms` of virtual time
/// for the page to finish, and returns what it wrote into <pre id="vdrig-result">.
inline PageResult load_page(const std::string& chromium, const std::string& url, const std::filesystem::path& profile,
                            int width, int height, int virtual_time_ms = 20000) {
  PageResult page;
  // Headless chromium as root needs --no-sandbox; its own profile folder keeps it away from $HOME.
  const std::vector<std::string> argv = {chromium,
                                         "--headless",
                                         "--no-sandbox",
                                         "--no-first-run",
                                         "--use-angle=swiftshader",
                                         "--enable-unsafe-swiftshader",
                                         "--force-device-scale-factor=1",
                                         "--window-size=" + std::to_string(width) + "," + std::to_string(height),
                                         "--user-data-dir=" + profile.string(),
                                         "--enable-logging=stderr",
                                         "--v=0",
                                         "--virtual-time-budget=" + std::to_string(virtual_time_ms),
                                         "--dump-dom",
                                         url};
  const ProcessRun run = run_process(argv, {120});
  if (run.exit_code != 0) {
    page.failure = "chromium exited " + std::to_string(run.exit_code) + ":\n" + run.err;
    return page;
  }
  std::istringstream lines(run.err);
  for (std::string line; std::getline(lines, line);)
    if (line.find(":CONSOLE") != std::string::npos) page.console_lines += line + "\n";
  const std::string open = "<pre id=\"vdrig-result\">";
  const auto start = run.out.find(open);
  const auto end = start == std::string::npos ? start : run.out.find("</pre>", start);
  if (end == std::string::npos) {
    page.failure = "no result in the page:\n" + run.out.substr(0, 2000) + "\n" + page.console_lines;
    return page;
  }
  std::string text = run.out.substr(start + open.size(), end - start - open.size());
  for (const auto& [entity, plain] :
       {std::pair{"&lt;", "<"}, std::pair{"&gt;", ">"}, std::pair{"&quot;", "\""}, std::pair{"&amp;", "&"}})
    for (size_t at = text.find(entity); at != std::string::npos; at = text.find(entity, at + 1))
      text.replace(at, std::string(entity).size(), plain);
  page.ran = !text.empty();
  page.result = text;
  if (!page.ran) page.failure = "the page wrote no result:\n" + page.console_lines;
  return page;
}

/// Why a test that runs node on a script driving chromium (puppeteer-core) cannot run here, empty when it can: no
/// chromium, no /usr/bin/node, or one of `modules` not installed in `folder`'s node_modules (the test skips then;
/// scripts/setup installs all three, npm ci from the folder's package-lock.json).
inline std::string node_browser_test_unavailable(const std::filesystem::path& folder,
                                                 const std::vector<std::string>& modules = {"puppeteer-core"}) {
  if (find_chromium().empty()) return "no chromium (scripts/setup installs it)";
  if (::access("/usr/bin/node", X_OK) != 0) return "no /usr/bin/node (scripts/setup installs nodejs)";
  for (const auto& m : modules)
    if (!std::filesystem::exists(folder / "node_modules" / m / "package.json"))
      return "no " + (folder / "node_modules" / m).string() + " (scripts/setup runs npm ci there)";
  return "";
}

}  // namespace vdrig::test

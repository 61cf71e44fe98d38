// Progress on stdout and log lines on stderr, both sent into one pipe (`vdrig demo 2>&1 | tee log`), come out in the
// order the program wrote them: vdrig's log sink flushes stdout before each log line (core/src/log.cpp). stdout into
// a pipe is block-buffered, so without that flush every log line would come out before the progress around it.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "vdrig/core/log.hpp"

namespace vdrig {
namespace {

TEST(LogOrder, ProgressAndLogLinesInOnePipeKeepTheirOrder) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  std::fflush(nullptr);  // nothing of the test's own buffered output may be written twice by the child
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(fds[0]);
    ::dup2(fds[1], STDOUT_FILENO);
    ::dup2(fds[1], STDERR_FILENO);
    ::close(fds[1]);
    // stdout is now a pipe: make it block-buffered as a freshly started program's would be.
    std::setvbuf(stdout, nullptr, _IOFBF, BUFSIZ);
    auto logger = log::get("order");
    std::printf("progress 1\n");
    logger->warn("log 1");
    std::printf("progress 2\n");
    logger->info("log 2");
    std::printf("progress 3\n");
    std::fflush(stdout);
    ::_exit(0);
  }
  ::close(fds[1]);
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  const size_t p1 = out.find("progress 1"), l1 = out.find("log 1"), p2 = out.find("progress 2"), l2 = out.find("log 2"),
               p3 = out.find("progress 3");
  ASSERT_NE(p1, std::string::npos) << out;
  ASSERT_NE(l1, std::string::npos) << out;
  ASSERT_NE(p2, std::string::npos) << out;
  ASSERT_NE(l2, std::string::npos) << out;
  ASSERT_NE(p3, std::string::npos) << out;
  EXPECT_LT(p1, l1) << out;
  EXPECT_LT(l1, p2) << out;
  EXPECT_LT(p2, l2) << out;
  EXPECT_LT(l2, p3) << out;
}

}  // namespace
}  // namespace vdrig

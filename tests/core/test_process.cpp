// vdrig::test::run_process / run_shell (tests/common/vdrig/test/process.hpp), which every process-level test uses
// to run vdrig, vdrigd, mpirun and the rest: what it reports against what /bin/sh was told to do. (Here with core's
// tests because the helper belongs to no module; it needs only a shell.)
#include <gtest/gtest.h>

#include "vdrig/test/process.hpp"

namespace vdrig::test {
namespace {

TEST(Process, CapturesStdoutStderrAndTheExitCode) {
  const ProcessRun r = run_shell("printf 'to out\\n'; printf 'to err\\n' >&2; exit 3");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.signal, 0);
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.out, "to out\n");
  EXPECT_EQ(r.err, "to err\n");
}

TEST(Process, MergedStderrIsInOutInOrder) {
  const ProcessRun r = run_shell("echo one; echo two >&2; echo three", {.merge_stderr = true});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.out, "one\ntwo\nthree\n");
  EXPECT_EQ(r.err, "");
}

TEST(Process, StdinIsEmpty) {
  const ProcessRun r = run_shell("wc -c | tr -d ' '");  // would otherwise read the test's own stdin (or wait)
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.out, "0\n");
}

TEST(Process, AHangIsKilledAtTheTimeLimitWithWhatItStarted) {
  // What the shell started (sleep) is killed with it: the group goes, so nothing outlives the test.
  const ProcessRun r = run_shell("echo started; sleep 30; echo never", {.timeout_s = 0.3});
  EXPECT_TRUE(r.timed_out);
  EXPECT_EQ(r.exit_code, 124);
  EXPECT_EQ(r.out, "started\n");
  EXPECT_LT(r.wall_s, 5.0);
  EXPECT_GE(r.wall_s, 0.3);
}

TEST(Process, ASignalIs128PlusItsNumber) {
  const ProcessRun r = run_process({"/bin/sh", "-c", "kill -KILL $$"});
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.signal, SIGKILL);
  EXPECT_EQ(r.exit_code, 128 + SIGKILL);
}

TEST(Process, AMissingProgramIs127) {
  const ProcessRun r = run_process({"/nonexistent/vdrig_no_such_program"});
  EXPECT_EQ(r.exit_code, 127);
}

TEST(Process, ShellQuoteKeepsEveryCharacter) {
  const std::string word = "it's a \"path\" with $HOME, `x` and \\ ;";
  const ProcessRun r = run_shell("printf '%s' " + shell_quote(word));
  EXPECT_EQ(r.out, word);
}

}  // namespace
}  // namespace vdrig::test

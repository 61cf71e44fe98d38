// core/process_lock.hpp: the device locks. A node (a serial port, a GPIO chip; here a pty and a plain file stand in
// for one) is locked with flock on the opened node, and a refusal names the holder's PID from /proc/locks; a device
// without a node is locked with a file in a fixed folder, whatever the process's runtime folder.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include "vdrig/core/process_lock.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {

TEST(DeviceLock, AnOpenNodeIsLockedOnceAndTheRefusalNamesTheHolder) {
  int controller = -1, port = -1;
  char name[256] = {};
  ASSERT_EQ(::openpty(&controller, &port, name, nullptr, nullptr), 0);
  const test::TempDir dir("core_device_lock");
  const std::string file = (dir.path() / "ttyFAKE").string();
  ::close(::open(file.c_str(), O_CREAT | O_WRONLY, 0644));
  for (const std::string& node : {std::string(name), file}) {
    SCOPED_TRACE(node);
    const int first = ::open(node.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    const int second = ::open(node.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    ASSERT_GE(first, 0);
    ASSERT_GE(second, 0);
    ASSERT_TRUE(lock_open_file(first, "serial port " + node));
    const Status refused = lock_open_file(second, "serial port " + node);
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error().code, ErrorCode::kInUse);
    EXPECT_EQ(refused.error().message, "serial port " + node + " is in use by PID " + std::to_string(::getpid()));
    ::close(first);  // closing releases it
    EXPECT_TRUE(lock_open_file(second, "serial port " + node));
    // Another process sees it held, and by whom.
    const pid_t child = ::fork();
    if (child == 0) {
      const int fd = ::open(node.c_str(), O_RDWR | O_NOCTTY);
      const Status s = lock_open_file(fd, "x");
      const bool named = !s && s.error().message == "x is in use by PID " + std::to_string(::getppid());
      ::_exit(named ? 0 : 1);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the child did not see our lock named";
    ::close(second);
  }
  ::close(port);
  ::close(controller);
}

TEST(DeviceLock, ANetworkDeviceIsLockedInAFixedFolder) {
  auto dir = device_lock_dir();
  ASSERT_TRUE(dir) << dir.error().describe();
  EXPECT_TRUE(dir.value() == "/run/lock/vdrig" || dir.value() == "/tmp/vdrig-locks") << dir.value();
  const std::string device = "test drive 127.0.0.1:" + std::to_string(::getpid());
  {
    auto held = lock_device(device);
    ASSERT_TRUE(held) << held.error().describe();
    auto refused = lock_device(device);
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error().code, ErrorCode::kInUse);
    EXPECT_EQ(refused.error().message, device + " is in use by PID " + std::to_string(::getpid()));
  }
  EXPECT_TRUE(lock_device(device)) << "released with its holder";
}

}  // namespace
}  // namespace vdrig

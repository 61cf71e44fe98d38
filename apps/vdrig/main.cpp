// `vdrig`: every subcommand. `vdrig rti ...` runs as the thin `vdrig-rti` beside this executable (issue #25): that
// process maps only what rti needs, not the ~100 libraries of the whole (libcamera, MPI, OpenSSL, GL...), whose
// shared pages were most of its peak memory. Same argv, so help, errors and exit codes are those of this executable.
#include <unistd.h>

#include <climits>
#include <cstring>

#include "cli.hpp"

namespace {

/// Execs vdrig-rti for `vdrig rti ...`; returns when it is not there (or not to be run), and vdrig runs the command
/// itself. An entry of .preinit_array, which the dynamic loader calls (with argc, argv, envp) before the libraries'
/// initialisers: the ~100 libraries are mapped by then, but none of their static constructors has run. libc only.
void exec_thin_rti(int argc, char** argv, char** /*envp*/) {
  const int sub = vdrig::app::subcommand_index(argc, argv);
  if (sub >= argc || std::strcmp(argv[sub], "rti") != 0) return;
  char path[PATH_MAX];
  const ssize_t length = ::readlink("/proc/self/exe", path, sizeof path);
  if (length <= 0 || static_cast<size_t>(length) >= sizeof path) return;
  path[length] = '\0';
  char* slash = std::strrchr(path, '/');
  const char kThin[] = "vdrig-rti";
  if (slash == nullptr || static_cast<size_t>(slash + 1 - path) + sizeof kThin > sizeof path) return;
  std::memcpy(slash + 1, kThin, sizeof kThin);
  ::execv(path, argv);  // returns only when it could not run (absent): the same command runs here
}

__attribute__((section(".preinit_array"), used)) void (*const kExecThinRti)(int, char**, char**) = exec_thin_rti;

}  // namespace

int main(int argc, char** argv) { return vdrig::app::run_cli(argc, argv); }

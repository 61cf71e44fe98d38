// `vdrig`: every subcommand. `vdrig rti ...` runs as the thin `vdrig-rti` beside this executable (issue #25): that
// process maps only what rti needs, not the ~100 libraries of the whole (libcamera, MPI, OpenSSL, GL...), whose
// shared pages were most of its peak memory. Same argv, so help, errors and exit codes are those of this executable.
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>

#include "cli.hpp"

int main(int argc, char** argv) {
  const int sub = vdrig::app::subcommand_index(argc, argv);
  if (sub < argc && std::strcmp(argv[sub], "rti") == 0) {
    std::error_code error;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
    if (!error) {
      const std::string thin = (self.parent_path() / "vdrig-rti").string();
      ::execv(thin.c_str(), argv);  // returns only when it could not run (absent): the same command runs here
    }
  }
  return vdrig::app::run_cli(argc, argv);
}

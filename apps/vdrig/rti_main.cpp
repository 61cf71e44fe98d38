// `vdrig-rti`: `vdrig rti` alone (issue #25), linked with only what its commands need (apps/CMakeLists.txt). vdrig
// execs it with its own argv (`vdrig rti fit ...`); typed by hand, `vdrig-rti fit ...` means the same.
#include <cstring>
#include <vector>

#include "cli.hpp"

int main(int argc, char** argv) {
  std::vector<char*> args(argv, argv + argc);
  const int sub = vdrig::app::subcommand_index(argc, argv);
  char rti[] = "rti";
  if (sub == argc || std::strcmp(argv[sub], "rti") != 0) args.insert(args.begin() + sub, rti);
  args.push_back(nullptr);
  return vdrig::app::run_cli(static_cast<int>(args.size()) - 1, args.data());
}

// Where this build's source tree, test data and executables are, for tests and benchmarks.
//
// The paths live in one source generated per build (build_paths.cpp in the build folder, cmake/VdrigTargets.cmake's
// vdrig_build_paths), not in -D definitions on every test: a test's object then holds no absolute path, so a fresh
// clone in another folder (CI's) compiles to the same object and hits the compiler cache (CCACHE_BASEDIR). A source
// that uses the macros includes this header (cmake's vdrig_use_build_paths links the paths and says whether the
// target may run vdrig); the macros keep the names the tests have always used.
#pragma once

namespace vdrig::test {
const char* source_dir();     ///< the repository's root
const char* test_data_dir();  ///< tests/data: the real data the tests read (tests/data/README.md)
const char* cli_path();       ///< the built `vdrig`
const char* vdrigd_path();    ///< the built `vdrigd`
}  // namespace vdrig::test

#define VDRIG_SOURCE_DIR (::vdrig::test::source_dir())
#define VDRIG_TEST_DATA_DIR (::vdrig::test::test_data_dir())
// Only for the targets that depend on the executables (vdrig_use_build_paths(... RUNS_VDRIG)): `#ifdef
// VDRIG_CLI_PATH` tells a test whether it may run them.
#ifdef VDRIG_TEST_RUNS_VDRIG
#define VDRIG_CLI_PATH (::vdrig::test::cli_path())
#define VDRIG_VDRIGD_PATH (::vdrig::test::vdrigd_path())
#endif

# Precompiled headers for the heavy third-party headers (below; docs/build-time.md).
option(VDRIG_PCH "Precompile the heavy third-party headers (cmake/pch/vdrig_pch/)" ON)

# Common compile options for every vdrig target.
add_library(vdrig_options INTERFACE)
target_compile_options(vdrig_options INTERFACE -Wall -Wextra -Wpedantic)
# GCC 12 reports false -Wrestrict positives inside std::string's operator+ at -O2 (GCC bug 105651). With the
# standard headers in a precompiled header (VDRIG_PCH, below) it also reports -Wstringop-overflow and -Warray-bounds
# inside std::char_traits::copy: their code is then inlined without the system-header mark that silences those
# middle-end warnings there. The asan preset's bounds checks and the fuzz preset's clang warnings still cover them.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  target_compile_options(vdrig_options INTERFACE -Wno-restrict)
  if(VDRIG_PCH)
    target_compile_options(vdrig_options INTERFACE -Wno-stringop-overflow -Wno-array-bounds)
  endif()
endif()
if(VDRIG_WERROR)
  target_compile_options(vdrig_options INTERFACE -Werror)
endif()
# LLVM's linker (Debian's lld, scripts/setup) where it is installed: the 130 test executables of a build link against
# the same large static libraries (with lld, all their links and discoveries took 88 s of the sanitizer build).
find_program(VDRIG_LLD ld.lld)
if(VDRIG_LLD)
  target_link_options(vdrig_options INTERFACE -fuse-ld=lld)
endif()
if(VDRIG_SANITIZE)
  target_compile_options(vdrig_options INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer
                                                 -fno-sanitize-recover=undefined)
  target_link_options(vdrig_options INTERFACE -fsanitize=address,undefined)
endif()
# Fuzzing build: every library gets libFuzzer's coverage hooks (fuzzer-no-link) and ASan + UBSan; the targets in
# fuzz/ add -fsanitize=fuzzer (libFuzzer's main). FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION is libFuzzer's usual
# switch for checks a mutated input can never pass (checksums): those are skipped so the fuzzer reaches the parser.
if(VDRIG_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "VDRIG_FUZZ needs clang (cmake --preset fuzz)")
  endif()
  target_compile_options(vdrig_options INTERFACE -fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer
                                                 -fno-sanitize-recover=undefined)
  target_compile_definitions(vdrig_options INTERFACE FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION)
  target_link_options(vdrig_options INTERFACE -fsanitize=address,undefined)
endif()

# Precompiled headers (docs/build-time.md): the third-party headers every source parsed again (OpenCV's core, Eigen,
# spdlog, nlohmann-json, the standard library; GoogleTest for the tests) are compiled once per build into a PCH that
# each target reuses: 2.5-3 s of a typical source's 9-11 s was spent parsing them (the rest is code generation). Three roots, since GCC and clang only
# accept a PCH compiled with the same code-generation flags as its user: libraries (position-independent), other
# executables' and libraries' objects, and the tests (common.hpp plus GoogleTest). Each root is an empty library with
# the usage requirements (include paths, definitions) of what its header includes; a target that reuses it gets the
# same, so that the macros the PCH saw match those of every source compiled with it.
# The headers are named in angle brackets, found through cmake/pch/: CMake then writes that name, not the clone's
# absolute path, into the generated cmake_pch.hxx, so that a fresh clone elsewhere (CI's) hits the compiler cache.
add_library(vdrig_pch_usage INTERFACE)
target_link_libraries(vdrig_pch_usage INTERFACE Eigen3::Eigen opencv_core nlohmann_json::nlohmann_json spdlog::spdlog)
target_include_directories(vdrig_pch_usage INTERFACE ${PROJECT_SOURCE_DIR}/cmake/pch)
function(vdrig_pch_root name header)
  set(source ${PROJECT_BINARY_DIR}/generated/${name}.cpp)
  file(GENERATE OUTPUT ${source} CONTENT "// The PCH root ${name} (cmake/VdrigTargets.cmake): no code of its own.\n")
  add_library(${name} STATIC ${source})
  target_link_libraries(${name} PRIVATE vdrig_options vdrig_pch_usage ${ARGN})
  target_precompile_headers(${name} PRIVATE ${header})
endfunction()
if(VDRIG_PCH)
  vdrig_pch_root(vdrig_pch_lib <vdrig_pch/common.hpp>)
  set_target_properties(vdrig_pch_lib PROPERTIES POSITION_INDEPENDENT_CODE ON)
  if(NOT VDRIG_FUZZ)  # a fuzzing build compiles its few executables (fuzz/) without one
    vdrig_pch_root(vdrig_pch_exe <vdrig_pch/common.hpp>)
  endif()
  if(VDRIG_BUILD_TESTS AND NOT VDRIG_FUZZ)
    vdrig_pch_root(vdrig_pch_test <vdrig_pch/test.hpp> GTest::gtest)
  endif()
endif()

# vdrig_use_pch(TARGET LIB|EXE|TEST): TARGET's sources are compiled with the precompiled header of its kind (above):
# LIB for a position-independent library, TEST for a test executable, EXE for anything else.
function(vdrig_use_pch target kind)
  if(NOT VDRIG_PCH)
    return()
  endif()
  string(TOLOWER ${kind} root)
  target_link_libraries(${target} PRIVATE vdrig_pch_usage)  # (a TEST target links GoogleTest already: vdrig_test)
  target_precompile_headers(${target} REUSE_FROM vdrig_pch_${root})
endfunction()

# vdrig_module(NAME SOURCES ... PUBLIC_DEPS ... PRIVATE_DEPS ...): one static library per module folder, as
# vdrig::NAME, with public headers in NAME/include/vdrig/NAME/ and private ones beside the sources in NAME/src/.
# Each module's CMakeLists.txt lists its sources explicitly in set(NAME_sources ...).
function(vdrig_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  if(NOT ARG_SOURCES)
    message(FATAL_ERROR "vdrig_module(${name}): no SOURCES")
  endif()
  add_library(vdrig_${name} STATIC ${ARG_SOURCES})
  add_library(vdrig::${name} ALIAS vdrig_${name})
  target_include_directories(vdrig_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include
                                           PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(vdrig_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE vdrig_options ${ARG_PRIVATE_DEPS})
  set_target_properties(vdrig_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  vdrig_use_pch(vdrig_${name} LIB)
endfunction()

# vdrig_build_paths_library(): vdrig_build_paths, this build's paths (source tree, tests/data, the built vdrig and
# vdrigd) compiled from one generated source, for tests/common/vdrig/test/build_paths.hpp. Called once, after apps/.
function(vdrig_build_paths_library)
  set(out ${PROJECT_BINARY_DIR}/generated/build_paths.cpp)
  file(GENERATE OUTPUT ${out} CONTENT "// Generated by cmake/VdrigTargets.cmake (vdrig_build_paths_library): this build's paths.
namespace vdrig::test {
const char* source_dir() { return R\"vdrig(${PROJECT_SOURCE_DIR})vdrig\"; }
const char* test_data_dir() { return R\"vdrig(${PROJECT_SOURCE_DIR}/tests/data)vdrig\"; }
const char* cli_path() { return R\"vdrig($<TARGET_FILE:vdrig>)vdrig\"; }
const char* vdrigd_path() { return R\"vdrig($<TARGET_FILE:vdrigd>)vdrig\"; }
}  // namespace vdrig::test
")
  add_library(vdrig_build_paths STATIC ${out})
endfunction()

# vdrig_use_build_paths(TARGET [RUNS_VDRIG]): TARGET's sources that include "vdrig/test/build_paths.hpp" see
# VDRIG_SOURCE_DIR, VDRIG_TEST_DATA_DIR and, with RUNS_VDRIG (which also builds vdrig and vdrigd first),
# VDRIG_CLI_PATH and VDRIG_VDRIGD_PATH. (Included by name, not force-included: a forced include before the
# precompiled header would keep the compiler from using it.)
function(vdrig_use_build_paths target)
  cmake_parse_arguments(ARG "RUNS_VDRIG" "" "" ${ARGN})
  target_link_libraries(${target} PRIVATE vdrig_build_paths)
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR}/tests/common)
  if(ARG_RUNS_VDRIG)
    add_dependencies(${target} vdrig vdrigd)
    target_compile_definitions(${target} PRIVATE VDRIG_TEST_RUNS_VDRIG)
  endif()
endfunction()

# vdrig_test(NAME SOURCES ... DEPS ... [LABELS ...] [TIMEOUT s]): one GoogleTest executable, tests discovered by
# CTest. Every test gets the shared helpers (vdrig::test_common, tests/common/) and VDRIG_TEST_DATA_DIR, the real
# data kept in tests/data (sources and licences in tests/data/README.md), through vdrig_use_build_paths.
function(vdrig_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} vdrig::test_common GTest::gtest GTest::gtest_main vdrig_options)
  vdrig_use_pch(${name} TEST)
  vdrig_use_build_paths(${name})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  # The longest tests start first (VDRIG_TEST_COST_<name>, tests/CMakeLists.txt): CTest orders a first run, which has
  # no timings of its own yet (a fresh clone's), by COST, so that a two-minute test does not start last and leave a
  # core idle at the end.
  set(cost 0)
  if(DEFINED VDRIG_TEST_COST_${name})
    set(cost ${VDRIG_TEST_COST_${name}})
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 TEST_PREFIX "${name}."
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}" SKIP_RETURN_CODE 77 COST ${cost}
                                  SKIP_REGULAR_EXPRESSION "\\[  SKIPPED \\]")
  # A module test that holds a figure the docs cite also gets the `fidelity` label (VDRIG_ALSO_FIDELITY,
  # tests/CMakeLists.txt). gtest_discover_tests cannot pass a list-valued property, so a CTest include file run after
  # the discovered tests' sets both labels on them (${name}_TESTS: their names, set by the discovery).
  if(name IN_LIST VDRIG_ALSO_FIDELITY)
    set(labels_file "${CMAKE_CURRENT_BINARY_DIR}/${name}_fidelity_labels.cmake")
    file(WRITE "${labels_file}"
         "if(${name}_TESTS)\n  set_tests_properties(\${${name}_TESTS} PROPERTIES LABELS \"${ARG_LABELS};fidelity\")\nendif()\n")
    set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${labels_file}")
  endif()
endfunction()

# vdrig_module_tests(MODULE [DEPS ...]): the tests of one module, called from tests/CMakeLists.txt. Each
# tests/MODULE/test_<name>.cpp is one executable MODULE_test_<name>, linked to vdrig::MODULE and DEPS and labelled
# MODULE (`ctest -L MODULE`); a new test file is picked up by its name.
function(vdrig_module_tests module)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${module}/test_*.cpp)
  foreach(src ${sources})
    get_filename_component(name ${src} NAME_WE)
    vdrig_test(${module}_${name} SOURCES ${src} DEPS vdrig::${module} ${ARG_DEPS} LABELS ${module})
  endforeach()
endfunction()

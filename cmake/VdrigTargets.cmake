# Common compile options for every vdrig target.
add_library(vdrig_options INTERFACE)
target_compile_options(vdrig_options INTERFACE -Wall -Wextra -Wpedantic)
# GCC 12 reports false -Wrestrict positives inside std::string's operator+ at -O2 (GCC bug 105651).
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  target_compile_options(vdrig_options INTERFACE -Wno-restrict)
endif()
if(VDRIG_WERROR)
  target_compile_options(vdrig_options INTERFACE -Werror)
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
endfunction()

# vdrig_test(NAME SOURCES ... DEPS ... [LABELS ...] [TIMEOUT s]): one GoogleTest executable, tests discovered by
# CTest. Every test gets the shared helpers (vdrig::test_common, tests/common/) and VDRIG_TEST_DATA_DIR, the real
# data kept in tests/data (sources and licences in tests/data/README.md).
function(vdrig_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} vdrig::test_common GTest::gtest GTest::gtest_main vdrig_options)
  target_compile_definitions(${name} PRIVATE VDRIG_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                                             VDRIG_TEST_DATA_DIR="${PROJECT_SOURCE_DIR}/tests/data")
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 TEST_PREFIX "${name}."
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}" SKIP_RETURN_CODE 77
                                  SKIP_REGULAR_EXPRESSION "\\[  SKIPPED \\]")
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

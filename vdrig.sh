#!/usr/bin/env bash
# vdrig.sh: the two things a new user does first.
#   ./vdrig.sh demo   set up, build, and run the whole pipeline on the simulated rig (writes images to out/demo)
#   ./vdrig.sh test   set up, build, and pass the tests (Release, the capture-only build, then under ASan + UBSan,
#                     then the fuzz targets); --quick: the Release build and its tests alone (a developer's loop)
# Other verbs: build, bench, results (regenerates docs/results.md), screenshots (regenerates docs/img/*.png),
# format-check, fuzz (each fuzz target for VDRIG_FUZZ_SECONDS, default 15; docs/fuzzing.md). Options after the verb go
# to the demo (see: build/apps/vdrig demo --help).
set -euo pipefail
cd "$(dirname "$0")"

verb=${1:-help}
shift || true
jobs=$(nproc)
# ccache: paths relative to this clone, so a fresh clone (CI) hits the cache an earlier clone filled.
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
# The precompiled headers (cmake/VdrigTargets.cmake): ccache caches a source compiled with one when these are sloppy
# (the PCH is hashed by its contents, and the PCH itself comes from the cache, byte for byte, in a warm build).
export CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime

setup() { bash scripts/setup "$@"; }

# Each phase's wall time, for docs/build-time.md's table: "== phase: N s (M s in all)".
phase_start=$SECONDS
phase_done() {
  echo "== $1: $((SECONDS - phase_start)) s ($SECONDS s in all)"
  phase_start=$SECONDS
}

# The relight-cli peer (tests/rti, bench_rti): built whenever its source is beside the repository, as CI's is; the
# tests then require it (VDRIG_REQUIRE_RELIGHT=1), so that a failed build or a missing binary fails the run instead of
# skipping its tests. Without the source the tests skip, naming it.
relight_peer() {
  local tarball=../shared/peers/relight/relight-src.tar.gz binary
  [ -f "$tarball" ] || { echo "relight-cli: no $tarball beside the repository: its tests will skip"; return 0; }
  binary=$(bash scripts/build_relight "$tarball" | tail -n 1)
  echo "relight-cli: $binary (its tests are required)"
  export VDRIG_RELIGHT_CLI=$binary VDRIG_REQUIRE_RELIGHT=1
}  # --tests: the npm packages the tests run are required (scripts/setup)

configure_and_build() {  # $1 = preset, then the targets to build (none: all of them)
  local preset=$1
  shift
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" -j "$jobs" ${1:+--target "$@"}
}

# OpenGL rendering needs an X display: use the user's, or a private Xvfb server.
with_display() {
  if [ -n "${DISPLAY:-}" ]; then "$@"; else xvfb-run -a -s "-screen 0 1280x1024x24" "$@"; fi
}

# Builds the fuzz preset (clang, ASan + UBSan); for every fuzz target replays its kept regression inputs
# (fuzz/regressions/<target>/) and then fuzzes for VDRIG_FUZZ_SECONDS (15) over a copy of its corpus
# (fuzz/corpus/<target>/; the fuzzer adds inputs to the copy, never to the repository). A crash stops the run; its
# input is written to build/fuzz/artifacts/ (keep it in fuzz/regressions/<target>/ once fixed).
run_fuzzers() {
  configure_and_build fuzz
  phase_done "fuzz build"
  local seconds=${VDRIG_FUZZ_SECONDS:-15} artifacts=$PWD/build/fuzz/artifacts work target name
  mkdir -p "$artifacts"
  work=$(mktemp -d)
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0
  export LSAN_OPTIONS=suppressions=$PWD/scripts/lsan.supp:print_suppressions=0
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # Readable stack traces (clang 16's runtimes look for a symbolizer of their own version, absent here).
  if command -v llvm-symbolizer >/dev/null; then export ASAN_SYMBOLIZER_PATH; ASAN_SYMBOLIZER_PATH=$(command -v llvm-symbolizer); fi
  for target in build/fuzz/fuzz/fuzz_*; do
    name=${target##*/fuzz_}
    [ "$name" = make_corpus ] && continue
    mkdir -p "$work/$name"
    cp -r fuzz/corpus/"$name"/. "$work/$name"/
    local flags=()  # fuzz/<target>.options: extra flags, one a line, # comments
    [ -f fuzz/"$name".options ] && mapfile -t flags < <(grep -v -e '^#' -e '^$' fuzz/"$name".options)
    local common=(-rss_limit_mb=2048 -timeout=25 -artifact_prefix="$artifacts/$name-")
    # The kept regression inputs are replayed once each, apart: as seeds, a slow one (the EXR targets keep inputs
    # that make OpenEXR allocate gigabytes) and its mutants would eat the whole fuzzing time.
    local regressions=()
    [ -d fuzz/regressions/"$name" ] && mapfile -t regressions < <(find fuzz/regressions/"$name" -type f | sort)
    echo "== fuzz_$name: ${#regressions[@]} regression inputs, then ${seconds} s"
    : >"$work/$name.log"
    if ! { [ ${#regressions[@]} -eq 0 ] || "$target" "${common[@]}" "${flags[@]}" "${regressions[@]}"; } \
      >>"$work/$name.log" 2>&1 ||
      ! "$target" -max_total_time="$seconds" -print_final_stats=1 "${common[@]}" "${flags[@]}" "$work/$name" \
        >>"$work/$name.log" 2>&1; then
      tail -n 80 "$work/$name.log" >&2
      echo "fuzz_$name failed: the input is in $artifacts/" >&2
      rm -rf "$work"
      return 1
    fi
    grep -E "^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)" "$work/$name.log" | tr '\n' ' ' || true
    echo
  done
  rm -rf "$work"
}

# The capture-only build (preset `capture`: a rig controller on a small board; docs/conventions.md, "Modules"):
# vdrig and vdrigd run, and link no OpenGL, GLFW or Ceres.
check_capture_build() {
  local bin=build/capture/apps libraries linked
  "$bin/vdrig" --help >/dev/null || return 1
  "$bin/vdrig" rig check --help >/dev/null || return 1
  "$bin/vdrigd/vdrigd" --help >/dev/null || return 1
  # Everything loaded (ldd), and what the executables themselves link (readelf): GLFW, the GL entry points (libGL,
  # libOpenGL, libEGL), Ceres and its glog/SuiteSparse must come in neither way. libGLX alone may: Debian's OpenCV
  # core is built with OpenGL interop and pulls it in, but no vdrig executable may link it itself. Nor OpenCV's
  # imgcodecs, highgui or videoio (and the GDAL they bring): ~0.15 s and 50 MB at every start (issue #25).
  libraries=$(ldd "$bin/vdrig" "$bin/vdrigd/vdrigd") || return 1
  linked=$(
    grep -Ei 'lib(GL|OpenGL|EGL|glfw|ceres|glog|cholmod|spqr)[.-]' <<<"$libraries" || true
    grep -Ei 'lib(opencv_imgcodecs|opencv_highgui|opencv_videoio|gdal)[.-]' <<<"$libraries" || true
    readelf -d "$bin/vdrig" "$bin/vdrigd/vdrigd" | grep NEEDED | grep -Ei 'lib(GL|OpenGL|GLX|EGL|glfw|ceres|glog)' || true
  )
  if [ -n "$linked" ]; then
    echo "the capture build links what it must not:" >&2
    echo "$linked" >&2
    return 1
  fi
  echo "capture build: vdrig and vdrigd run, no OpenGL, GLFW, Ceres or OpenCV imgcodecs linked"
}

# The web console's screenshots (docs/web.md, README): vdrigd on the simulated rig and `vdrig serve` on loopback, in a
# temporary folder, shot by tests/web/browser/screenshots.mjs in headless Chromium; the viewer's shots use a copy of
# the demo's session (out/demo/session, fitted by the report screenshots before) when there is one.
web_screenshots() {  # $1 = vdrig, $2 = vdrigd
  local work daemon server url showcase=""
  work=$(mktemp -d)
  mkdir -p "$work/run" "$work/sessions"
  if [ -f out/demo/session/maps/phong:1.exr ] && [ -f out/demo/session/calib/views.json ]; then
    cp -r out/demo/session "$work/sessions/demo"
    showcase="demo 60"  # the session and a captured view of its middle ring
  fi
  "$2" --runtime-dir "$work/run" --sessions-dir "$work/sessions" --reserve-mb 0 --log-level warn &
  daemon=$!
  "$1" serve --runtime-dir "$work/run" --sessions-dir "$work/sessions" --port 0 >"$work/url" 2>/dev/null &
  server=$!
  for _ in $(seq 100); do [ -s "$work/url" ] && break; sleep 0.1; done
  url=$(head -n 1 "$work/url")
  (cd tests/web/browser && [ -d node_modules/puppeteer-core ] || npm ci --no-audit --no-fund)
  local status=0
  node tests/web/browser/screenshots.mjs "$url" /usr/bin/chromium "$work/profile" docs/img $showcase || status=$?  # (unquoted: two words or none)
  kill "$server" "$daemon"
  wait "$server" "$daemon" || true
  rm -rf "$work"
  return $status
}

case "$verb" in
  demo)
    # Only the vdrig executable: the demo runs nothing else, and the 82 test programs and 13 benchmarks of a full
    # build took two thirds of a fresh machine's time (./vdrig.sh build or test builds them).
    setup
    configure_and_build release vdrig
    echo "setup and build: ${SECONDS} s"
    with_display build/release/apps/vdrig demo --out out/demo "$@"
    echo "./vdrig.sh demo: ${SECONDS} s in all (setup, build and the demo)"
    ;;
  test)
    quick=0
    [ "${1:-}" = --quick ] && quick=1
    setup --tests
    phase_done setup
    # Every test runs under a display here (Xvfb when there is none): an OpenGL test that finds no context fails
    # instead of skipping (tests/common/vdrig/test/require_gl.hpp).
    export VDRIG_REQUIRE_GL=1
    relight_peer
    phase_done "relight-cli peer"
    configure_and_build ci
    phase_done "ci build"
    with_display ctest --preset ci
    phase_done "Release tests"
    [ "$quick" -eq 1 ] && exit 0
    configure_and_build capture
    check_capture_build
    phase_done "capture build and link check"
    configure_and_build asan
    phase_done "asan build"
    export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0
    export LSAN_OPTIONS=suppressions=$PWD/scripts/lsan.supp:print_suppressions=0
    export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
    # intercept_tls_get_addr=0 (here and in run_fuzzers): the sanitizer runtimes of GCC 12 and of clang before 17
    # guess that a dynamic TLS block whose address is 16 bytes past a page boundary carries a pre-2.25 glibc header,
    # and read its "start" and "size" from the 16 bytes before it. Since glibc 2.25 there is no such header; a block
    # that lands on that offset by chance (seen on viewer_test_render_models, an OpenGL test) gives LeakSanitizer a
    # bogus range, and its stop-the-world tracer dies at exit ("Tracer caught signal 11") after the test passed. Being
    # a matter of memory layout, it failed the same test again on a rerun. A dlopen'd library with 8 to 100 bytes of
    # TLS touched by 300 threads alive at exit crashes the tracer in 5 runs of 5, and in none with this option. The
    # interceptor only adds dynamic TLS as a root of the leak scan: without it a leak could be reported that is not
    # one, never one hidden (none is).
    with_display ctest --preset asan
    phase_done "ASan + UBSan tests"
    run_fuzzers
    phase_done "fuzzing"
    ;;
  fuzz)
    setup
    run_fuzzers
    ;;
  build)
    setup
    configure_and_build release
    ;;
  bench)
    setup
    configure_and_build release
    for b in build/release/bench/bench_*; do echo "== $b"; with_display "$b"; done
    ;;
  results)
    setup
    configure_and_build release
    build/release/bench/bench_results_table docs/results.md
    ;;
  screenshots)
    setup
    configure_and_build release
    bash scripts/screenshots.sh build/release/apps/vdrig docs/img
    VDRIG=build/release/apps/vdrig bash scripts/report_screenshots.sh
    web_screenshots build/release/apps/vdrig build/release/apps/vdrigd/vdrigd
    ;;
  format-check)
    setup
    git ls-files '*.cpp' '*.hpp' | xargs clang-format --dry-run -Werror
    ;;
  *)
    sed -n '2,8p' "$0"
    exit 2
    ;;
esac

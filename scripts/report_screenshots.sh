#!/usr/bin/env bash
# Regenerates the report screenshots in docs/img/ (docs/report.md, README) from the demo's session:
#   vdrig demo (when out/demo has no fitted map) -> vdrig calib extrinsics (when it has no calib/views.json: the
#   report marks the views it excludes) -> vdrig compare --views held-out -> vdrig report -> headless Chromium.
# VDRIG=path/to/vdrig uses that executable instead of building the release preset.
set -euo pipefail
cd "$(dirname "$0")/.."
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
bash scripts/setup
vdrig=${VDRIG:-}
if [ -z "$vdrig" ]; then
  cmake --preset release >/dev/null
  cmake --build --preset release -j "$(nproc)" --target vdrig
  vdrig=build/release/apps/vdrig
fi
with_display() {
  if [ -n "${DISPLAY:-}" ]; then "$@"; else xvfb-run -a -s "-screen 0 1280x1024x24" "$@"; fi
}

session=out/demo/session
[ -f "$session/maps/phong:1.exr" ] || with_display "$vdrig" demo --out out/demo
[ -f "$session/calib/views.json" ] || "$vdrig" calib extrinsics "$session"
with_display "$vdrig" compare "$session" --maps phong:1 --views held-out
"$vdrig" report "$session" --out out/demo/report.html --texel 20,100
ls -l out/demo/report.html

# One screenshot per anchor: the report in a 1280-pixel-wide frame scrolled to the section.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p docs/img
shot() {  # $1 = section id, $2 = output PNG, $3 = height in pixels
  printf '<html><body style="margin:0"><iframe src="file://%s#%s" style="border:0;width:1280px;height:%dpx">' \
    "$PWD/out/demo/report.html" "$1" "$3" >"$work/frame.html"
  printf '</iframe></body></html>\n' >>"$work/frame.html"
  chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --no-first-run --user-data-dir="$work/profile" \
    --allow-file-access-from-files --virtual-time-budget=3000 --window-size=1280,"$3" --screenshot="$2" \
    "file://$work/frame.html" >/dev/null 2>&1
  echo "screenshot: $2"
}
shot coverage docs/img/report_coverage.png 1000
shot maps docs/img/report_maps.png 1150
shot calibration docs/img/report_calibration.png 420

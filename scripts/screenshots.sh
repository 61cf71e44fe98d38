#!/usr/bin/env bash
# Regenerates the viewer screenshots of docs/viewer.md and the README (docs/img/*.png) from a fresh simulated
# session: `vdrig demo` (capture, HDR, Phong-1 fit with 3 held-out views), an SH-36 fit of the same session, then
# scripted `vdrig view` frames (a model, the difference at a held-out view, the texel inspector) and a
# `vdrig inspect` plot. Usage: scripts/screenshots.sh [VDRIG_BINARY] [OUT_DIR]   (./vdrig.sh screenshots)
# Needs an X display (or runs under xvfb-run); takes about as long as the demo.
set -euo pipefail
cd "$(dirname "$0")/.."
vdrig=$(realpath "${1:-build/release/apps/vdrig}")
out=${2:-docs/img}
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

run() { if [ -n "${DISPLAY:-}" ]; then "$@"; else xvfb-run -a -s "-screen 0 1280x1024x24" "$@"; fi; }

run "$vdrig" demo --out "$work/demo" | tee "$work/demo.log"
session=$work/demo/session
phong=$session/maps/phong:1.exr
sh=$session/maps/sh-ls:6.exr
"$vdrig" fit "$session" --model sh-ls:6 --res 128x128 --holdout 3 --out "$sh"
# The first held-out view the demo compared ("    view N: mean |render - photo| ...").
view=$(sed -n 's/^ *view \([0-9]*\): mean.*/\1/p' "$work/demo.log" | head -n 1)
# A texel on the glossy plastic patch (x 50..400, y -400..-50 mm of the 1000 mm patchwork surface).
texel=92,35
common=(--session "$session" --constrained --view "$view" --frames 3 --hidden --max-window 1024)

run "$vdrig" view "$phong" "$sh" "${common[@]}" --screenshot "$out/viewer_model.png"
run "$vdrig" view "$phong" "$sh" "${common[@]}" --display difference --screenshot "$out/viewer_difference.png"
run "$vdrig" view "$phong" "$sh" "${common[@]}" --map 1 --display difference \
  --screenshot "$out/viewer_difference_sh36.png"
run "$vdrig" view "$phong" "$sh" "${common[@]}" --inspect "$texel" --screenshot "$out/viewer_inspector.png"
"$vdrig" inspect "$phong" --session "$session" --texel "$texel" --out "$out/inspect_phong.png"
"$vdrig" inspect "$sh" --session "$session" --texel "$texel" --out "$out/inspect_sh36.png"
echo "screenshots (view $view, texel $texel) in $out"

#!/usr/bin/env bash
# The viewer's benchmark (docs/benchmarks.md), under Xvfb (Mesa's llvmpipe) at 1280x720:
#  1. frame time with a 200k-triangle mesh while the estimate runs in the background;
#  2. time from pressing Estimate to the first usable estimate (the first finished round)
#     on the demo scene (the bundled recording, reconstructed in the window first).
# Usage: scripts/bench-viewer.sh [OUT_DIR]   (builds first; prints the figures)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh >/dev/null
out=${1:-build/bench-viewer}; mkdir -p "$out"
exe=build/app/lightprobe
$exe synth one-light --min-triangles 200000 --out "$out/scene200k" >/dev/null
cat >"$out/frames.txt" <<EOS
wait-open 120
frames 10
estimate
wait-first 600
bench-frames 300
state $out/frames.json
bench-frames 100 orbit
screenshot $out/frames.png
state $out/frames-orbit.json
cancel
quit
EOS
xvfb-run -a -s "-screen 0 1280x720x24 -noreset" $exe view "$out/scene200k" --script "$out/frames.txt" >"$out/frames.log" 2>&1
cat >"$out/first.txt" <<EOS
wait-open 120
live off
speed 0
reconstruct start
play
wait-end 600
reconstruct stop
frames 5
estimate
wait-first 600
state $out/first.json
wait-estimate 900
state $out/done.json
screenshot $out/done.png
quit
EOS
xvfb-run -a -s "-screen 0 1280x720x24 -noreset" $exe view demo --script "$out/first.txt" >"$out/first.log" 2>&1
echo "frame time, 1280x720, $(grep -o '"shown_triangles": [0-9]*' "$out/frames.json"), estimating:"
grep -A8 '"bench"' "$out/frames.json"
echo "the same, orbiting (the 3D view redrawn every frame):"
grep -A8 '"bench"' "$out/frames-orbit.json"
echo "Estimate -> first usable estimate on the demo: $(grep -o '"seconds_to_first": [0-9.]*' "$out/first.json")"
echo "Estimate -> done: $(grep -o '"seconds_total": [0-9.]*' "$out/done.json")"

#!/usr/bin/env bash
# A real recording's held-out frame (issue 41): the Redwood PrimeSense frames 0-3
# reconstructed and estimated, frame 4 (assets/rgbd/redwood_open3d/holdout/holdout.json)
# relit under the estimate by `lightprobe evaluate`, its error split into the light's part
# (both images blurred by 4 px) and the colour map's (what the blur takes away). No
# truth.json: no light is scored. The figures are real data's; the test checks they are
# there and consistent (the blurred error below the whole, the two parts adding up in
# quadrature), not their size (docs/benchmarks.md has them).
set -eu
exe="$1"; data="$2"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" reconstruct "$data/RGBD" --max-frames 4 --keyframes 2 --out "$out/run/scene" >"$out/log" 2>&1 ||
  { cat "$out/log"; echo "reconstruct failed"; exit 1; }
"$exe" estimate "$out/run/scene" --out "$out/run/estimate" --rings 9 --spp 16 --max-rounds 2 --render-spp 8 \
  --albedo-passes 1 --quiet >>"$out/log" 2>&1 || { cat "$out/log"; echo "estimate failed"; exit 1; }
"$exe" evaluate "$out/run" --truth "$data" --spp 8 >"$out/eval" 2>&1 || { cat "$out/eval"; exit 1; }
cat "$out/eval"
read_json() { python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(eval(sys.argv[2], {}, {'j': j}))" "$1" "$2"; }
e="$out/run/evaluation.json"
[ "$(read_json "$e" "len(j['lamps'])")" = 0 ] && [ "$(read_json "$e" "j['spurious_share']")" = None ] ||
  { echo "lamps scored without a truth.json"; exit 1; }
covered=$(read_json "$e" "j['held_out_relit_covered']")
blurred=$(read_json "$e" "j['held_out_relit_blurred']")
sharp=$(read_json "$e" "j['held_out_colour_map_part']")
share=$(read_json "$e" "j['held_out_covered']")
check_between "the held-out frame's share the reconstruction covers" "$share" 0.2 1 || exit 1
check_between "the held-out relit error over the covered pixels" "$covered" 0.001 2 || exit 1
check_below "the blurred error (the light's part) against the whole" "$blurred" "$covered" || exit 1
sum=$(python3 -c "import math; print(abs(math.hypot($blurred, $sharp) - $covered))")
check_below "light's and colour map's parts in quadrature against the whole" "$sum" 1e-6 || exit 1
[ "$(read_json "$out/run/estimate/report.json" "j['evaluation']['held_out_relit_blurred']")" = "$blurred" ] ||
  { echo "report.json without the evaluation"; exit 1; }
echo "redwood held-out frame: relit $covered over $share of it; the light's part $blurred, the colour map's $sharp"

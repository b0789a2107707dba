#!/usr/bin/env bash
# Lamps from a scan (issue 41), end to end: a small copy of the shared Blender Cycles scan
# (tests/data/cycles-scans/scan_one_lamp_small: a textured room, one lamp 1.51 m from its
# centre, 20 frames at 320x240, 8-bit sRGB colour, Kinect-like depth noise) through
# `--headless` with its true poses (frames -> reconstruction -> albedo from the colours
# seen -> lights), scored by `lightprobe evaluate` against the renderer's truth: the lamp
# within 10 % of its distance, light x albedo and the albedo's scale within 1.5x, no
# spurious lamp over 5 %.
set -eu
exe="$1"; scan="$2"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" --headless "$scan" --poses "$scan/trajectory.log" --use-poses --out "$out/run" >"$out/log" 2>&1 ||
  { cat "$out/log"; echo "headless failed"; exit 1; }
"$exe" evaluate "$out/run" --truth "$scan" --spp 16 >"$out/eval" 2>&1 || { cat "$out/eval"; exit 1; }
read_json() { python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(eval(sys.argv[2], {}, {'j': j}))" "$out/run/evaluation.json" "$1"; }
share=$(read_json "j['lamps'][0]['error_share']")
product=$(read_json "j['lamps'][0]['light_times_albedo']")
scale=$(read_json "j['albedo_scale']")
spurious=$(read_json "j['spurious_share']")
p90=$(read_json "j['mesh']['p90_m']")
albedo_error=$(read_json "j['albedo_error']")
covered=$(read_json "j['held_out_relit_covered']")
blurred=$(read_json "j['held_out_relit_blurred']")
cat "$out/eval"
check_below "the lamp's error over its distance" "$share" 0.10 || exit 1
check_between "light x albedo" "$product" 0.667 1.5 || exit 1
check_between "the albedo's scale" "$scale" 0.667 1.5 || exit 1
check_below "the largest spurious lamp's share" "$spurious" 0.05 || exit 1
check_below "the mesh's 90th percentile from the true surface (m)" "$p90" 0.02 || exit 1
# The albedo against the truth once its scale is undone (0.13 on this copy), and the
# held-out error's light part (both images blurred) below the whole (the colour map's
# sharpness is the rest); both also in the estimate's report.json.
check_below "the albedo's error once its scale is undone" "$albedo_error" 0.3 || exit 1
check_below "the held-out error's light part (blurred) against the whole" "$blurred" "$covered" || exit 1
python3 -c "import json,sys; e=json.load(open(sys.argv[1]))['evaluation']; sys.exit(0 if e['albedo_error'] == $albedo_error else 1)" \
  "$out/run/estimate/report.json" || { echo "report.json without the evaluation"; exit 1; }
echo "scan: lamp $share of its distance off, light x albedo $product, albedo's scale $scale (its error $albedo_error), mesh p90 $p90 m, held-out $covered ($blurred blurred)"

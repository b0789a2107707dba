#!/usr/bin/env bash
# A lamp where the camera saw it (issue 43): synthetic RGB-D frames in which the lamp's
# sphere is seen at its radiance (clipped in the 8-bit frames) and returns no depth, as a
# bare bulb does. `reconstruct` keeps those pixels as clipped off the mesh
# (clipped_off<k>.png); the estimate triangulates the blobs across keyframes and its search
# tries that place (report.json -> model.seen_lamps) and holds the lamp there.
set -eu
exe="$1"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" synth lamp-and-sky --frames 12 --lamps-seen --spp 16 --out "$out/f" >"$out/log" 2>&1 || { cat "$out/log"; exit 1; }
"$exe" reconstruct "$out/f" --poses "$out/f/trajectory.log" --out "$out/s" >"$out/rlog" 2>&1 || { cat "$out/rlog"; exit 1; }
ls "$out/s/"clipped_off*.png >/dev/null 2>&1 || { echo "no clipped_off mask in the bundle"; exit 1; }
# e1: the seen places tried and a lamp held there; f1: tried, not held; e0: not tried.
for run in "e1 1 1" "f1 1 0" "e0 0 1"; do
  read -r name seen hold <<<"$run"
  "$exe" estimate "$out/s" --out "$out/$name" --seen-lamps $seen --hold-seen $hold --max-rounds 1 --albedo-passes 0 \
    --render-noise 0 >"$out/log$name" 2>&1 || { cat "$out/log$name"; exit 1; }
done
lamp_off() {  # the estimate's lamp nearest the truth: its distance, whether held, its distance from the seen place
  python3 - "$out/f/truth.json" "$out/$1/lights.json" "$out/e1/report.json" <<'PY'
import json, math, sys
truth = json.load(open(sys.argv[1]))["lights"][0]["position"]
lamps = json.load(open(sys.argv[2]))["point_lights"]
seen = json.load(open(sys.argv[3]))["model"]["seen_lamps"]
lamp = min(lamps, key=lambda l: math.dist(l["position"], truth)) if lamps else {"position": [1e9] * 3}
print(math.dist(lamp["position"], truth), int(lamp.get("held", False)),
      math.dist(lamp["position"], seen[0]["position"]) if seen else 1e9)
PY
}
read -r off count how <<<"$(python3 - "$out/f/truth.json" "$out/e1/report.json" <<'PY'
import json, math, sys
truth = json.load(open(sys.argv[1]))["lights"][0]["position"]
seen = json.load(open(sys.argv[2]))["model"]["seen_lamps"]
print(math.dist(seen[0]["position"] if seen else [1e9] * 3, truth), len(seen), seen[0]["how"] if seen else "none")
PY
)"
read -r lamp held from_seen <<<"$(lamp_off e1)"
read -r free_lamp free_held free_from_seen <<<"$(lamp_off f1)"
[ "$count" = 1 ] || { echo "seen places: $count, one wanted"; grep "clipped blob" "$out/elog1"; exit 1; }
[ "$how" = triangulated ] || { echo "the bulb's place came $how, not triangulated"; exit 1; }
# The blobs' mean pixels at 160 x 120 (a pixel is 1.7 cm at the lamp's 2.5 m from the cameras).
check_below "the seen place's distance from the lamp (m)" "$off" 0.02 || exit 1
# The lamp the estimate keeps is held at the seen place (its place measured, not refined);
# refined from there (--hold-seen 0) it moves, and stays within 10 % of its 1.5 m from the
# scene's centre.
[ "$held" = 1 ] || { echo "the lamp is not held at the seen place"; grep "seen place" "$out/loge1"; exit 1; }
check_below "the held lamp's distance from the seen place (m)" "$from_seen" 1e-6 || exit 1
[ "$free_held" = 0 ] || { echo "--hold-seen 0 still held the lamp"; exit 1; }
check_below "the refined lamp's distance from the true one (m)" "$free_lamp" 0.15 || exit 1
check_below "the seen place's distance from the refined lamp (m), at least" 1e-4 "$free_from_seen" || exit 1
# The search's first light starts there (the place explains the light best of its candidates).
grep -q "light 1 starts from the place where the camera saw clipped blob 1" "$out/e1/report.json" ||
  { echo "the search's first light did not start from the seen place"; grep -o '"search: light[^"]*"' "$out/e1/report.json"; exit 1; }
grep -q "light 1 starts from the grid around the scene" "$out/e0/report.json" ||
  { echo "without seen places the first light did not start from the grid"; exit 1; }
n0=$(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['model']['seen_lamps']))" "$out/e0/report.json")
[ "$n0" = 0 ] || { echo "--seen-lamps 0 still tried $n0 seen place(s)"; exit 1; }
echo "a bulb with no depth: triangulated $off m from the lamp and held there; refined from there, $free_lamp m off"

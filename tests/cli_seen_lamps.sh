#!/usr/bin/env bash
# A lamp where the camera saw it (issue 43): synthetic RGB-D frames in which the lamp's
# sphere is seen at its radiance (clipped in the 8-bit frames) and returns no depth, as a
# bare bulb does. `reconstruct` keeps those pixels as clipped off the mesh
# (clipped_off<k>.png); the estimate triangulates the blobs across keyframes and its search
# tries that place (report.json -> model.seen_lamps); the lamp comes back near it.
set -eu
exe="$1"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" synth lamp-and-sky --frames 12 --lamps-seen --spp 16 --out "$out/f" >"$out/log" 2>&1 || { cat "$out/log"; exit 1; }
"$exe" reconstruct "$out/f" --poses "$out/f/trajectory.log" --out "$out/s" >"$out/rlog" 2>&1 || { cat "$out/rlog"; exit 1; }
ls "$out/s/"clipped_off*.png >/dev/null 2>&1 || { echo "no clipped_off mask in the bundle"; exit 1; }
for seen in 1 0; do
  "$exe" estimate "$out/s" --out "$out/e$seen" --seen-lamps $seen --max-rounds 1 --albedo-passes 0 --render-noise 0 \
    >"$out/elog$seen" 2>&1 || { cat "$out/elog$seen"; exit 1; }
done
read -r off count how lamp <<<"$(python3 - "$out/f/truth.json" "$out/e1/report.json" "$out/e1/lights.json" <<'PY'
import json, math, sys
truth = json.load(open(sys.argv[1]))["lights"][0]["position"]
report = json.load(open(sys.argv[2]))
seen = report["model"]["seen_lamps"]
lamps = json.load(open(sys.argv[3]))["point_lights"]
place = seen[0]["position"] if seen else [1e9] * 3
lamp = min((math.dist(l["position"], truth) for l in lamps), default=1e9)
print(math.dist(place, truth), len(seen), seen[0]["how"] if seen else "none", lamp)
PY
)"
[ "$count" = 1 ] || { echo "seen places: $count, one wanted"; grep "clipped blob" "$out/elog1"; exit 1; }
[ "$how" = triangulated ] || { echo "the bulb's place came $how, not triangulated"; exit 1; }
# The blobs' mean pixels at 160 x 120 (a pixel is 1.7 cm at the lamp's 2.5 m from the cameras).
check_below "the seen place's distance from the lamp (m)" "$off" 0.02 || exit 1
# The lamp the estimate keeps, 1.5 m from the scene's centre: within 10 % of that.
check_below "the estimated lamp's distance from the true one (m)" "$lamp" 0.15 || exit 1
# The search's first light starts there (the place explains the light best of its candidates).
grep -q "light 1 starts from the place where the camera saw clipped blob 1" "$out/e1/report.json" ||
  { echo "the search's first light did not start from the seen place"; grep -o '"search: light[^"]*"' "$out/e1/report.json"; exit 1; }
grep -q "light 1 starts from the grid around the scene" "$out/e0/report.json" ||
  { echo "without seen places the first light did not start from the grid"; exit 1; }
n0=$(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['model']['seen_lamps']))" "$out/e0/report.json")
[ "$n0" = 0 ] || { echo "--seen-lamps 0 still tried $n0 seen place(s)"; exit 1; }
echo "a bulb with no depth: triangulated $off m from the lamp; the estimate's lamp $lamp m off"

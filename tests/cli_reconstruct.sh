#!/usr/bin/env bash
# The main job end to end on the bundled demo recording, headless: .oni -> reconstruct
# (tracking, bundle with its truth) -> estimate. Bad input to reconstruct: one clear line,
# exit 2.
set -eu
exe="$1"; demo="$2"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" --headless "$demo/demo.oni" --poses "$demo/trajectory.log" --keyframes 2 --out "$out/h" >"$out/log" 2>&1 ||
  { cat "$out/log"; exit 1; }
mv "$out/h/scene" "$out/scene"
[ -s "$out/h/estimate/report.json" ] || { echo "headless wrote no estimate"; exit 1; }
for f in scene.json mesh.ply view0.exr mask0.png view1.exr truth.json reconstruction.csv trajectory.log; do
  [ -s "$out/scene/$f" ] || { echo "missing $f"; exit 1; }
done
grep -q "0 lost" "$out/log" || { cat "$out/log"; echo "tracking was lost"; exit 1; }
ate=$(sed -n 's/.*trajectory error against the given poses: \([0-9.]*\) mm.*/\1/p' "$out/log")
check_below "trajectory error (mm)" "$ate" 20 || { cat "$out/log"; exit 1; }
head -1 "$out/scene/reconstruction.csv" | grep -q "^frame,state,seconds," || exit 1
err=$(grep -o '"angular_error_deg": [0-9.e+-]*' "$out/h/estimate/report.json" | head -1 | awk '{print $2}')
# The demo is lit by a lamp 1.5 m from the room's centre and a dim sky: the headless run finds
# the lamp's direction from the scene within 10 degrees (4.1 with this seed and 2 keyframes)
# and it is a point light, within 35 % of its distance from the mesh's centre (see
# docs/method.md, known gaps: the reconstruction's albedo and the dim sky the map drops).
check_below "dominant light error (deg)" "$err" 10 || exit 1
share=$(grep -o '"position_error_share": [0-9.e+-]*' "$out/h/estimate/report.json" | head -1 | awk '{print $2}')
check_below "lamp position error / distance" "$share" 0.35 || exit 1
grep -q "the lamp is [0-9.]* cm from the true one" "$out/log" || { echo "headless did not print the lamp's error"; exit 1; }

# Albedo refinement: the reconstructed mesh carries the colours seen; the estimate de-lit
# them, segmented again and wrote the de-lit mesh. --albedo-passes 0 and a bundle with known
# albedo (no colours seen) leave it out and say why.
grep -a -q "property float shaded_red" "$out/scene/mesh.ply" || { echo "mesh.ply without the colours seen"; exit 1; }
grep -q "albedo pass 1: de-lit" "$out/log" && grep -q '"refined": true' "$out/h/estimate/report.json" &&
  [ -s "$out/h/estimate/albedo_mesh.ply" ] || { echo "albedo refinement did not run"; exit 1; }
# Its rounds are logged as such (error against run time through the refinement).
head -1 "$out/h/estimate/convergence.csv" | grep -q ",albedo_pass$" && grep -q ",0$" "$out/h/estimate/convergence.csv" &&
  grep -q ",1$" "$out/h/estimate/convergence.csv" || { echo "convergence.csv without the albedo pass"; exit 1; }
# The albedo's absolute scale (--room-albedo): without refinement the scaled albedo the
# lights go with is still written; with the colours' scale too (0), nothing is.
"$exe" estimate "$out/scene" --out "$out/off" --albedo-passes 0 --max-rounds 1 --spp 8 --render-spp 8 --rings 9 \
  >"$out/olog" 2>&1 || { cat "$out/olog"; exit 1; }
grep -q '"why_not": "--albedo-passes 0"' "$out/off/report.json" && [ -s "$out/off/albedo_mesh.ply" ] ||
  { echo "refinement not left out with --albedo-passes 0, or the scaled albedo not written"; exit 1; }
scale=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['albedo']['scale'])" "$out/off/report.json")
check_between "the albedo's scale" "$scale" 1.5 50 || exit 1
"$exe" estimate "$out/scene" --out "$out/off0" --albedo-passes 0 --room-albedo 0 --max-rounds 1 --spp 8 \
  --render-spp 8 --rings 9 >"$out/olog0" 2>&1 || { cat "$out/olog0"; exit 1; }
[ ! -e "$out/off0/albedo_mesh.ply" ] || { echo "an unscaled, unrefined albedo was written"; exit 1; }
"$exe" estimate "$demo/../demo" --out "$out/known" --max-rounds 1 --spp 8 --render-spp 8 --rings 9 \
  >"$out/klog" 2>&1 || { cat "$out/klog"; exit 1; }
grep -q "albedo is known" "$out/known/report.json" && [ ! -e "$out/known/albedo_mesh.ply" ] ||
  { echo "a bundle with known albedo was refined"; exit 1; }

# No arguments and no display: the viewer says so and points to --headless.
set +e; env -u DISPLAY -u WAYLAND_DISPLAY "$exe" >"$out/noargs" 2>&1; rc=$?; set -e
[ "$rc" -eq 2 ] && grep -q -- "--headless" "$out/noargs" || { echo "no-argument run: exit $rc"; cat "$out/noargs"; exit 1; }

# Bad input: one line, exit 2, nothing written.
empty="$out/empty"; mkdir -p "$empty/color" "$empty/depth"
for args in "$out/missing.oni --out $out/x" "$empty --out $out/x" "$demo/demo.oni --out $out/x --voxel 0" \
            "$demo/demo.oni --out $out/x --poses $out/missing.log"; do
  set +e; "$exe" reconstruct $args >"$out/bad" 2>&1; rc=$?; set -e
  [ "$rc" -eq 2 ] || { echo "reconstruct $args: exit $rc"; cat "$out/bad"; exit 1; }
  [ "$(grep -c . "$out/bad" | tr -d ' ')" -le 2 ] || { echo "reconstruct $args: more than one error line"; cat "$out/bad"; exit 1; }
  [ ! -e "$out/x" ] || { echo "reconstruct $args wrote output"; exit 1; }
done
echo "reconstruct ok: trajectory error $ate mm, dominant light error $err deg, lamp position error $share of its distance"

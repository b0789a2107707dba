#!/usr/bin/env bash
# Bad input gets one clear line naming the file and a non-zero exit, never a crash.
set -u
exe="$1"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
expect() {  # expect <pattern> <command...>
  local pattern="$1"; shift
  "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  local lines
  lines=$(wc -l <"$tmp/err")
  if [ "$rc" -ne 2 ] || ! grep -q -- "$pattern" "$tmp/err" || [ "$lines" -ne 1 ]; then
    echo "FAIL: $* -> rc=$rc, stderr:"; cat "$tmp/err"; fail=1
  else
    echo "ok: $(cat "$tmp/err")"
  fi
}
expect "scene directory not found" "$exe" estimate "$tmp/nope" --out "$tmp/o" --quiet
mkdir -p "$tmp/s" && echo '{"views": [' >"$tmp/s/scene.json"
expect "scene.json: malformed JSON" "$exe" estimate "$tmp/s" --out "$tmp/o" --quiet
echo '{"views": [{"image": "v.exr", "width": 4, "height": 4, "fx": 1, "fy": 1, "cx": 1, "cy": 1, "world_from_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}' >"$tmp/s/scene.json"
expect "mesh.ply: file not found" "$exe" estimate "$tmp/s" --out "$tmp/o" --quiet
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n' >"$tmp/s/mesh.ply"
expect "mesh.ply: mesh has no non-degenerate triangles" "$exe" estimate "$tmp/s" --out "$tmp/o" --quiet
expect "unknown solver" "$exe" estimate "$tmp/s" --out "$tmp/o" --solver newton --quiet
expect "unknown synthetic scene" "$exe" synth nope --out "$tmp/x"
# --headless's estimate options are checked before the reconstruction's work, and nothing is written
expect "not expected: 1 --bogus" "$exe" --headless "$tmp/nope.oni" --out "$tmp/hb" --estimate-options "--bogus 1"
[ -e "$tmp/hb" ] && { echo "FAIL: --headless wrote $tmp/hb before refusing its estimate options"; fail=1; }
expect "--estimate-options is not taken with --live" "$exe" --headless "$tmp/nope.oni" --out "$tmp/hb" --live --estimate-options "--seed 2"
expect "exactly one of --envmap, --uniform or --lights" "$exe" render "$tmp/s" --out "$tmp/o"
printf "{\"point_lights\": [{\"position\": [0, 0, 1], \"intensity\": [1, -1, 1]}]}" > "$tmp/bad_lights.json"
expect "intensity is negative" "$exe" render "$tmp/s" --out "$tmp/o" --lights "$tmp/bad_lights.json"
mkdir -p "$tmp/est" && cp "$tmp/bad_lights.json" "$tmp/est/lights.json"
expect "lights.json: .*intensity is negative" "$exe" export "$tmp/s" "$tmp/est" --format gltf --out "$tmp/o"
expect "lights.json: file not found" "$exe" export "$tmp/s" "$tmp/nope" --format sh --out "$tmp/o"
expect "expected blender, gltf or sh, got 'obj'" "$exe" export "$tmp/s" "$tmp/est" --format obj --out "$tmp/o"
expect "nee-floor must be between 0 and 1, not 2" "$exe" estimate "$tmp/s" --out "$tmp/o" --nee-floor 2 --quiet
expect "albedo-passes must be between 0 and 5, not 9" "$exe" estimate "$tmp/s" --out "$tmp/o" --albedo-passes 9 --quiet
expect "albedo-samples must be between 1 and 4096, not 0" "$exe" estimate "$tmp/s" --out "$tmp/o" --albedo-samples 0 --quiet
expect "rings must be a whole number, not '21.5'" "$exe" estimate "$tmp/s" --out "$tmp/o" --rings 21.5 --quiet
expect "spp must be at least 1, not 0" "$exe" estimate "$tmp/s" --out "$tmp/o" --spp 0 --quiet
expect "room-albedo must be between 0 and 0.95, not 2" "$exe" estimate "$tmp/s" --out "$tmp/o" --room-albedo 2 --quiet
expect "albedo-settle must be between 0 and 1, not -0.1" "$exe" estimate "$tmp/s" --out "$tmp/o" --albedo-settle -0.1 --quiet
expect "no truth.json, gt_mesh.ply nor holdout/holdout.json: nothing to score against" "$exe" evaluate "$tmp/run" --truth "$tmp/s"
echo '{"lights": []}' >"$tmp/truth.json"
expect "run/scene: scene directory not found" "$exe" evaluate "$tmp/run" --truth "$tmp"
expect "evaluate: --spp must be at least 1" "$exe" evaluate "$tmp/run" --truth "$tmp/s" --spp 0
expect "smooth: Value -1 not in range" "$exe" reconstruct "$tmp/nope" --out "$tmp/o" --smooth -1
expect "unknown-flag" "$exe" estimate "$tmp/s" --out "$tmp/o" --unknown-flag
# A valid scene with bad settings: refused before any work (a negative sigma once looped).
"$exe" synth one-light --out "$tmp/good" --width 16 --height 12 --spp 1 >/dev/null 2>&1 || { echo "FAIL: synth"; fail=1; }
for sigma in -1 0 nan; do
  expect "sigma must be positive and finite" timeout 60 "$exe" estimate "$tmp/good" --out "$tmp/o" --sigma "$sigma" --quiet
done
# A truncated view image: OpenCV's own complaint is not printed, ours is the one line.
cp -r "$tmp/good" "$tmp/trunc" && head -c 300 "$tmp/good/view0.exr" >"$tmp/trunc/view0.exr"
expect "view0.exr: cannot decode image" "$exe" estimate "$tmp/trunc" --out "$tmp/o" --quiet
[ ! -e "$tmp/o/report.json" ] || { echo "FAIL: output written on error"; fail=1; }
exit $fail

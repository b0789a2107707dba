#!/usr/bin/env bash
# `export SCENE ESTIMATE --format blender|gltf|sh --out DIR` from the command line, on a real
# estimate (the lamp-1m scene, 64 x 48): each format writes its files, and what they say
# agrees with the estimate's lights.json: the blender script's lamp has power 4 pi I, the glTF
# point light's candela are 683 I (the colour normalized), lighting.json carries the lamp and
# nine RGB coefficients each way. A wrong format is a clear error and a non-zero exit.
set -eu
exe="$1"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$exe" synth lamp-1m --out "$tmp/s" --width 64 --height 48 --spp 64 >/dev/null
"$exe" estimate "$tmp/s" --out "$tmp/e" --quiet >/dev/null
for f in blender gltf sh; do
  "$exe" export "$tmp/s" "$tmp/e" --format $f --out "$tmp/$f" > "$tmp/$f.log"
  grep -q "^wrote $tmp/$f" "$tmp/$f.log" || { echo "export $f: no 'wrote' line"; cat "$tmp/$f.log"; exit 1; }
done
python3 - "$tmp" <<'PY'
import json, math, re, sys
t = sys.argv[1]
lights = json.load(open(t + "/e/lights.json"))
lamp = lights["point_lights"]
assert len(lamp) == 1, lights
I = lamp[0]["intensity"]
for f in ("scene.py", "mesh.ply"):
    open(t + "/blender/" + f, "rb").read(1)
script = open(t + "/blender/scene.py").read()
block = script.split("POINT_LIGHTS = [", 1)[1].split("]\n", 1)[0]
nums = [float(x) for x in re.findall(r"-?\d+\.?\d*(?:e[+-]?\d+)?", block)]
power = 4 * math.pi * max(I)
assert any(abs(n - power) < 1e-3 * power for n in nums), ("no power 4 pi I = %g in" % power, block)
g = json.load(open(t + "/gltf/scene.gltf"))
pl = [l for l in g["extensions"]["KHR_lights_punctual"]["lights"] if l["type"] == "point"]
assert len(pl) == 1, pl
cd = pl[0]["intensity"]
assert abs(cd - 683 * max(I)) < 1e-3 * cd, (cd, I)
assert abs(max(pl[0]["color"]) - 1) < 1e-6, pl[0]["color"]
assert open(t + "/gltf/scene.bin", "rb").read(1)
sh = json.load(open(t + "/sh/lighting.json"))
for k in ("frame", "sh9_radiance", "sh9_irradiance", "main_light", "point_lights", "directional_lights"):
    assert k in sh, k
for k in ("sh9_radiance", "sh9_irradiance"):
    assert len(sh[k]) == 9 and all(len(c) == 3 for c in sh[k]), (k, sh[k])
assert len(sh["point_lights"]) == 1 and sh["directional_lights"] == []
print("export: blender lamp power %.4g W, glTF %.4g cd, lighting.json with %d lamp" % (power, cd, len(sh["point_lights"])))
PY
if "$exe" export "$tmp/s" "$tmp/e" --format obj --out "$tmp/x" > "$tmp/err" 2>&1; then echo "--format obj accepted"; exit 1; fi
[ "$(wc -l < "$tmp/err")" -le 2 ] && grep -qi "format" "$tmp/err" || { echo "unclear error for --format obj:"; cat "$tmp/err"; exit 1; }
echo "export ok"

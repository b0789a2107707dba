#!/usr/bin/env bash
# `render SCENE --lights FILE [--mesh FILE]` relights a bundle under a lights.json: a synthetic
# lamp scene (its image from the renderer's sphere light) rendered under a lights.json that
# holds the true lamp as a point light of the same radius and no map comes back within the
# Monte Carlo noise of both images; the same lamp moved 10 cm does not (the check can fail);
# --mesh with the bundle's own mesh gives the same render as without it, and with the mesh's
# albedo halved a render about half as bright; --lights refuses --envmap and --uniform beside
# it; a lights.json's environment is found beside the file, not in the working directory.
# Then the estimate of that scene: its lights.json, report.json (the model chosen and why,
# each round's lights) and convergence.csv (the lamps' columns) say one lamp near the true
# one, and its lights.json relights the scene as the true lamp does.
set -eu
exe="$1"
. "$(dirname "$0")/check_number.sh"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$exe" synth lamp-1m --out "$tmp/s" --width 64 --height 48 --spp 256 >/dev/null
# The true lamp: a uniform sphere of power P has radiant intensity P / 4 pi.
python3 - "$tmp" <<'PY'
import json, math, sys
t = sys.argv[1]
lamp = json.load(open(t + "/s/truth.json"))["lights"][0]
I = [p / (4 * math.pi) for p in lamp["rgb_power"]]
def write(name, dz):
    pos = list(lamp["position"]); pos[2] += dz
    json.dump({"point_lights": [{"position": pos, "intensity": I, "radius": lamp["radius"]}]}, open(t + "/" + name, "w"))
write("true.json", 0.0)
write("moved.json", 0.10)
# The bundle's mesh with every albedo halved (linear; the PLY's colours are sRGB-encoded).
data = open(t + "/s/mesh.ply", "rb").read()
head_end = data.index(b"end_header\n") + len(b"end_header\n")
head = data[:head_end].decode()
assert "binary_little_endian" in head and "property float nz\nproperty uchar red" in head, head
n = int(head.split("element vertex ")[1].split()[0])
def dec(v): v /= 255; return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4
def enc(v): return round(255 * (12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055))
body = bytearray(data[head_end:])
for i in range(n):
    for c in range(3):
        k = i * 27 + 24 + c  # 6 floats, then red, green, blue
        body[k] = enc(0.5 * dec(body[k]))
open(t + "/half.ply", "wb").write(data[:head_end] + bytes(body))
PY
rmse() { sed -n 's/^view 0: relative RMSE against the bundle.s image \([0-9.e+-]*\)$/\1/p'; }
true_err=$("$exe" render "$tmp/s" --lights "$tmp/true.json" --out "$tmp/r" --spp 256 | rmse)
moved_err=$("$exe" render "$tmp/s" --lights "$tmp/moved.json" --out "$tmp/m" --spp 256 | rmse)
mesh_err=$("$exe" render "$tmp/s" --lights "$tmp/true.json" --mesh "$tmp/s/mesh.ply" --out "$tmp/k" --spp 256 | rmse)
half_err=$("$exe" render "$tmp/s" --lights "$tmp/true.json" --mesh "$tmp/half.ply" --out "$tmp/h" --spp 256 | rmse)
echo "relative RMSE: true lamp $true_err, moved 10 cm $moved_err, --mesh (the bundle's own) $mesh_err, (albedo halved) $half_err"
for f in render_view0.exr render_view0.png; do [ -s "$tmp/r/$f" ] || { echo "missing $f"; exit 1; }; done
# Both images at 256 spp (measured: the true lamp 0.037, moved 10 cm 0.192).
check_below "the true lamp's render against the image" "$true_err" 0.08
check_below "the true lamp's error, under a quarter of the moved lamp's" "$(awk -v a="$true_err" -v b="$moved_err" 'BEGIN { print 4 * a - b }')" 0
[ "$mesh_err" = "$true_err" ] || { echo "--mesh with the bundle's own mesh: $mesh_err, without it $true_err"; exit 1; }
# Half the albedo: the direct light half, the interreflections a quarter and less, so the
# render well under half the image's brightness (measured 0.69; the true mesh's 0.037).
check_between "the render with the halved albedo (--mesh) against the image" "$half_err" 0.5 0.85

# --lights stands alone: a map or a uniform sky beside it is refused, one line, non-zero.
for other in "--envmap $tmp/x.exr" "--uniform 1,1,1"; do
  if "$exe" render "$tmp/s" --lights "$tmp/true.json" $other --out "$tmp/x" >"$tmp/err" 2>&1; then
    echo "render --lights with $other was accepted"; exit 1
  fi
  grep -q "excludes" "$tmp/err" || { echo "render --lights with $other: unclear error:"; cat "$tmp/err"; exit 1; }
done
# A lights.json's environment is a path relative to the file: rendered from elsewhere, the
# same as the map given by --envmap (same seed: the same number).
mkdir -p "$tmp/l"
cp "$(dirname "$0")/../assets/hdri/studio_small_03_1k.hdr" "$tmp/l/sky.hdr"
echo '{"environment": "sky.hdr", "point_lights": [], "directional_lights": []}' > "$tmp/l/lights.json"
env_err=$(cd "$tmp" && "$exe" render "$tmp/s" --lights l/lights.json --out "$tmp/el" --spp 16 | rmse)
map_err=$("$exe" render "$tmp/s" --envmap "$tmp/l/sky.hdr" --out "$tmp/em" --spp 16 | rmse)
echo "the environment of a lights.json: $env_err, the same map by --envmap: $map_err"
is_number "$env_err" && [ "$env_err" = "$map_err" ] || { echo "lights.json's environment: $env_err, --envmap: $map_err"; exit 1; }

"$exe" estimate "$tmp/s" --out "$tmp/e" --quiet
python3 - "$tmp" <<'PY'
import csv, json, math, sys
t = sys.argv[1]
truth = json.load(open(t + "/s/truth.json"))["lights"][0]["position"]
def off(p): return math.dist(p, truth)
lights = json.load(open(t + "/e/lights.json"))
assert len(lights["point_lights"]) == 1, lights
assert off(lights["point_lights"][0]["position"]) < 0.05, ("lights.json", lights["point_lights"])
report = json.load(open(t + "/e/report.json"))
assert report["model"]["chosen"] == "environment map + 1 point light(s)", report["model"]["chosen"]
# and why: the kept lamp's line gives its held-out loss with and without it
why = [l for l in report["model"]["choices"] if "held-out loss" in l and l.endswith("kept")]
assert len(why) == 1, report["model"]["choices"]
assert all(len(r["point_lights"]) == 1 for r in report["rounds"]), "a round without its lamp"
assert off(report["rounds"][-1]["point_lights"][0]["position"]) < 0.05
rows = list(csv.DictReader(open(t + "/e/convergence.csv")))
last = rows[-1]
assert last["point_lights"] == "1" and float(last["position_error_m"]) < 0.05, last
print("estimate: lamp %.1f cm off; report.json and convergence.csv agree" % (100 * off(lights["point_lights"][0]["position"])))
PY
est_err=$("$exe" render "$tmp/s" --lights "$tmp/e/lights.json" --out "$tmp/re" --spp 256 | rmse)
echo "relative RMSE under the estimate's lights.json: $est_err"
check_below "the estimate's lights.json relit against the image" "$est_err" 0.08
echo "render --lights ok"

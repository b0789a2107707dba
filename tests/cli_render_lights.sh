#!/usr/bin/env bash
# `render SCENE --lights FILE [--mesh FILE]` relights a bundle under a lights.json: a synthetic
# lamp scene (its image from the renderer's sphere light) rendered under a lights.json that
# holds the true lamp as a point light of the same radius and no map comes back within the
# Monte Carlo noise of both images; the same lamp moved 10 cm does not (the check can fail);
# --mesh with the bundle's own mesh gives the same render as without it.
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
PY
rmse() { sed -n 's/^view 0: relative RMSE against the bundle.s image \([0-9.e+-]*\)$/\1/p'; }
true_err=$("$exe" render "$tmp/s" --lights "$tmp/true.json" --out "$tmp/r" --spp 256 | rmse)
moved_err=$("$exe" render "$tmp/s" --lights "$tmp/moved.json" --out "$tmp/m" --spp 256 | rmse)
mesh_err=$("$exe" render "$tmp/s" --lights "$tmp/true.json" --mesh "$tmp/s/mesh.ply" --out "$tmp/k" --spp 256 | rmse)
echo "relative RMSE: true lamp $true_err, moved 10 cm $moved_err, --mesh (the bundle's own) $mesh_err"
for f in render_view0.exr render_view0.png; do [ -s "$tmp/r/$f" ] || { echo "missing $f"; exit 1; }; done
# Both images at 256 spp (measured: the true lamp 0.037, moved 10 cm 0.192).
check_below "the true lamp's render against the image" "$true_err" 0.08
check_below "the true lamp's error, under a quarter of the moved lamp's" "$(awk -v a="$true_err" -v b="$moved_err" 'BEGIN { print 4 * a - b }')" 0
[ "$mesh_err" = "$true_err" ] || { echo "--mesh with the bundle's own mesh: $mesh_err, without it $true_err"; exit 1; }
echo "render --lights ok"

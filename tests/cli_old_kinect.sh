#!/usr/bin/env bash
# Other people's files (issue 22): a 12-frame Kinect v1 recording made with OpenNI 1 tools
# (tests/data/oni/3dj_test.oni, MIT) runs through the whole headless pipeline (replay ->
# reconstruct -> estimate) with intrinsics from what the file holds and says which;
# `--intrinsics FILE` replaces them in replay, and a bad intrinsics file is one clear line.
set -eu
exe="$1"; file="$2"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# (no clean render: half the test's time, and nothing here looks at it)
"$exe" --headless "$file" --keyframes 2 --out "$out/h" --estimate-options "--render-noise 0" >"$out/log" 2>&1 || { cat "$out/log"; echo "headless failed"; exit 1; }
grep -q "intrinsics of the colour camera from the depth stream's field of view" "$out/log" ||
  { cat "$out/log"; echo "no note of where the intrinsics came from"; exit 1; }
for f in scene/scene.json scene/mesh.ply scene/view0.exr estimate/lights.json estimate/report.json; do
  [ -s "$out/h/$f" ] || { echo "missing $f"; exit 1; }
done
tracked=$(sed -n 's/.*12 frames in .*: \([0-9]*\) tracked.*/\1/p' "$out/log")
check_between "frames tracked of 12" "$tracked" 11 12 || { cat "$out/log"; exit 1; }
# Up points up (issue 41): the recording sees a ceiling and no floor, and the bundle's world
# is the first camera's frame, whose y points down: up has a clearly negative y. (With the
# ceiling's normal turned towards the camera it came out (0.03, 0.96, -0.28).)
up_y=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['up'][1])" "$out/h/scene/scene.json")
check_between "the bundle's up, its y in the first camera's frame" "$up_y" -1 -0.7 || exit 1
# The window (issue 43): a bright curtained window at the left of frame 6, clipped by the
# camera (pixels x 140-280, y 140-330 of 640 x 480; the bundle's world is the first camera's
# frame, and the camera barely moves). The keyframes carry its clipped pixels
# (clipped<k>.png), and the estimate keeps a glowing surface there: the centroid of an
# emitter in emitters.ply projects into those pixels (fx 575.8, centre (320, 240)).
ls "$out/h/scene/"clipped*.png >/dev/null 2>&1 || { echo "no clipped mask in the bundle"; exit 1; }
python3 - "$out/h/estimate/emitters.ply" <<'PY' || exit 1
import struct, sys
data = open(sys.argv[1], "rb").read()
head = data.index(b"end_header\n") + len(b"end_header\n")
header = data[:head].decode()
assert "property int emitter" in header, "emitters.ply has no emitter ids"
count = int([l for l in header.split("\n") if l.startswith("element vertex")][0].split()[-1])
per, off = {}, head
for _ in range(count):  # x y z nx ny nz (float), red green blue (uchar), emitter (int), radiance_r/g/b (float)
    x, y, z = struct.unpack_from("<3f", data, off)
    (e,) = struct.unpack_from("<i", data, off + 27)
    per.setdefault(e, []).append((x, y, z))
    off += 43
hits = []
for e, p in per.items():
    c = [sum(q[k] for q in p) / len(p) for k in range(3)]
    u, v = 320 + 575.8 * c[0] / c[2], 240 + 575.8 * c[1] / c[2]
    print("emitter %d: %d triangles, centroid (%.2f, %.2f, %.2f), pixel (%.0f, %.0f)" % (e, len(p) // 3, *c, u, v))
    hits.append(140 <= u <= 280 and 140 <= v <= 330)
if not any(hits):
    sys.exit("no emitter at the window")
# No surface glows twice: no triangle (its three corners, in order) in two emitters. (The
# search found a kept surface's pixels glowing again and kept a part of it as a second,
# overlapping emitter.)
owner = {}
for e, p in per.items():
    for t in range(0, len(p) - 2, 3):
        key = tuple(p[t:t + 3])
        assert owner.setdefault(key, e) == e, "a triangle in emitters %d and %d" % (owner[key], e)
PY
# The keyframes' cameras carry the file's focal length: 575.8 px at 640 px, 143.95 in the
# bundle's 160 px views (575.8 / 4).
fx=$(grep -o '"fx": [0-9.e+-]*' "$out/h/scene/scene.json" | head -1 | awk '{print $2}')
check_between "keyframe fx" "$fx" 143.9 144.0 || exit 1

echo '{"width": 640, "height": 480, "fx": 530.5, "fy": 530.5, "cx": 320, "cy": 240}' >"$out/k.json"
"$exe" replay "$file" --intrinsics "$out/k.json" --frames 1 >"$out/replay" 2>&1 || { cat "$out/replay"; exit 1; }
grep -q "fx 530.5, registered" "$out/replay" || { cat "$out/replay"; echo "--intrinsics not used"; exit 1; }
echo '{"width": 320, "height": 240, "fx": 265, "fy": 265, "cx": 160, "cy": 120}' >"$out/small.json"
set +e
"$exe" replay "$file" --intrinsics "$out/small.json" --frames 1 >"$out/bad" 2>&1
code=$?
set -e
[ "$code" = 2 ] && grep -q "small.json: intrinsics for 320x240, but the colour frames are 640x480" "$out/bad" ||
  { cat "$out/bad"; echo "a mismatched intrinsics file was not one clear line with exit 2 (exit $code)"; exit 1; }
# reconstruct takes --intrinsics too (the keyframes at 160 px: 530.5 / 4), and a
# calibration's camera wins over it (600 / 4).
"$exe" reconstruct "$file" --intrinsics "$out/k.json" --max-frames 3 --keyframes 1 --out "$out/k" >"$out/klog" 2>&1 ||
  { cat "$out/klog"; exit 1; }
kfx=$(grep -o '"fx": [0-9.e+-]*' "$out/k/scene.json" | head -1 | awk '{print $2}')
check_between "keyframe fx with --intrinsics" "$kfx" 132.62 132.63 || exit 1
cat >"$out/cal.json" <<'JSON'
{"format": "lightprobe-calibration", "version": 1,
 "camera": {"width": 640, "height": 480, "fx": 600, "fy": 600, "cx": 319.5, "cy": 239.5}}
JSON
"$exe" reconstruct "$file" --calibration "$out/cal.json" --intrinsics "$out/k.json" --max-frames 3 --keyframes 1 \
  --out "$out/c" >"$out/clog" 2>&1 || { cat "$out/clog"; exit 1; }
cfx=$(grep -o '"fx": [0-9.e+-]*' "$out/c/scene.json" | head -1 | awk '{print $2}')
check_between "keyframe fx with --calibration and --intrinsics" "$cfx" 149.99 150.01 || exit 1
echo "old Kinect recording: headless ok, up y $up_y, fx $fx, $tracked of 12 frames tracked; --intrinsics $kfx, --calibration wins $cfx"

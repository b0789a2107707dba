#!/usr/bin/env bash
# The capture commands end to end, no camera: synthetic frames -> record through OpenNI2
# (the project's driver) -> replay the .oni into a frame directory -> replay that; bad input
# gives one line and exit code 2.
set -eu
exe="$1"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" synth one-light --frames 5 --width 64 --height 48 --spp 8 --out "$out/frames" >/dev/null
[ -s "$out/frames/trajectory.log" ] && [ -s "$out/frames/intrinsics.json" ] || { echo "frame directory incomplete"; exit 1; }
"$exe" record --source "lpsynth://$out/frames" --frames 8 --out "$out/rec.oni" >/dev/null
# 8 depth frames read while recording; the Recorder keeps every frame the device sends until
# its streams stop, so a loaded machine records more (the synthetic device catches up on a
# stall in a burst, as a camera's driver delivers what queued): 7 .. 20 replayed pairs.
"$exe" replay "$out/rec.oni" --out "$out/back" >"$out/replay.log"
count=$(sed -n 's/^\([0-9]*\) frames in .*/\1/p' "$out/replay.log")
[ "${count:-0}" -ge 7 ] && [ "${count:-0}" -le 20 ] || { echo "replay count: $(head -3 "$out/replay.log")"; exit 1; }
n=$(ls "$out/back/depth" | wc -l)
[ "$n" -ge 7 ] || { echo "exported $n frames"; exit 1; }
"$exe" replay "$out/back" --start 2 --frames 3 | grep -q "^3 frames" || { echo "replay --start/--frames"; exit 1; }
# Bad input: a truncated recording and a missing directory.
head -c 1000 "$out/rec.oni" > "$out/cut.oni"
set +e
msg=$("$exe" replay "$out/cut.oni" 2>&1); rc=$?
set -e
[ "$rc" -eq 2 ] || { echo "truncated .oni: exit $rc"; exit 1; }
echo "$msg" | grep -q "truncated" || { echo "truncated .oni: '$msg'"; exit 1; }
set +e
"$exe" record --frames 2 --out "$out/none.oni" 2>"$out/err"; rc=$?
set -e
[ "$rc" -eq 2 ] && [ "$(wc -l <"$out/err")" -eq 1 ] || { echo "no camera: exit $rc, $(cat "$out/err")"; exit 1; }
[ ! -e "$out/none.oni" ] || { echo "a failed recording left a file"; exit 1; }
echo "capture commands ok"

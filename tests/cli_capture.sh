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
"$exe" record --source "lpsynth://$out/frames" --frames 8 --out "$out/rec.oni" >"$out/record.log"
# 8 depth frames read while recording; the Recorder keeps every frame the device sends until
# its streams stop, so how many the file holds depends on how busy the machine is. What does
# not: the counts the command reports are the side file's, the replay gives the fewer of
# them in frame pairs (OpenNI2's index of the file), and exports every one of them; of the
# 8 depth frames read, all are held but perhaps one that arrived before the Recorder started.
depth=$(sed -n 's/^recorded \([0-9]*\) depth and \([0-9]*\) colour frames.*/\1/p' "$out/record.log")
color=$(sed -n 's/^recorded \([0-9]*\) depth and \([0-9]*\) colour frames.*/\2/p' "$out/record.log")
grep -q "\"depth_frames\": ${depth:-none}," "$out/rec.oni.json" && grep -q "\"color_frames\": ${color:-none}," "$out/rec.oni.json" ||
  { echo "record reports ${depth:-none} / ${color:-none} frames, the side file: $(cat "$out/rec.oni.json")"; exit 1; }
pairs=$(( depth < color ? depth : color ))
"$exe" replay "$out/rec.oni" --out "$out/back" >"$out/replay.log"
count=$(sed -n 's/^\([0-9]*\) frames in .*/\1/p' "$out/replay.log")
[ "${count:-0}" -eq "$pairs" ] || { echo "replayed ${count:-none} pairs, the file holds $pairs: $(head -3 "$out/replay.log")"; exit 1; }
[ "$depth" -ge 7 ] || { echo "the file holds $depth depth frames of the 8 read"; exit 1; }
n=$(ls "$out/back/depth" | wc -l)
[ "$n" -eq "$count" ] || { echo "exported $n of $count frames"; exit 1; }
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

#!/usr/bin/env bash
# Regenerates assets/demo-recording/: the bundled demo as an .oni recording of a synthetic
# scene, made through the real OpenNI2 stack (the project's lpsynth driver serves the
# rendered frames as a device, OpenNI2's Recorder writes the file), with its ground truth.
# Usage: scripts/make-demo-recording.sh [path/to/lightprobe]   (~3 min on 2 cores)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/app/lightprobe}
served=48 recorded=40
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$exe" synth lamp-and-sky --frames $served --width 320 --height 240 --spp 128 --depth-noise --out "$tmp/frames"
mkdir -p "$tmp/out"
"$exe" record --source "lpsynth://$tmp/frames" --frames $recorded --lossy-color --out "$tmp/out/demo.oni"
# The synthetic device numbers frames from 1 and serves directory frame (index - 1): the
# recording starts at directory frame $first; its poses are the lines that follow.
first=$(( $(sed -n 's/.*"first_depth_frame_index": *\([0-9-]*\).*/\1/p' "$tmp/out/demo.oni.json") - 1 ))
# The depth frames the file holds (the side file counts them; under load it can be more
# than were asked for): one pose each.
held=$(sed -n 's/.*"depth_frames": *\([0-9]*\).*/\1/p' "$tmp/out/demo.oni.json")
if (( first < 0 || held < recorded || first + held > served )); then
  echo "make-demo-recording: the recording holds depth frames $first..$((first + held - 1)) of $served (expected $recorded from near 0)" >&2
  exit 1
fi
awk -v first=$first -v n=$held 'BEGIN { k = -1 }
  NR % 5 == 1 { k = (NR - 1) / 5 - first; if (k >= 0 && k < n) print k, k, k + 1; next }
  k >= 0 && k < n { print }' "$tmp/frames/trajectory.log" > "$tmp/out/trajectory.log"
cp "$tmp/frames/truth.json" "$tmp/frames/intrinsics.json" "$tmp/out/"
rm -rf "$root/assets/demo-recording.new"
cp -r "$tmp/out" "$root/assets/demo-recording.new"
rm -rf "$root/assets/demo-recording"
mv "$root/assets/demo-recording.new" "$root/assets/demo-recording"
echo "wrote $root/assets/demo-recording (directory frames $first..$((first + held - 1)) of $served)"

#!/usr/bin/env bash
# The live pipeline soaked (issue 44): the window (under Xvfb when there is no display) on
# the project's own OpenNI2 driver serving synthetic frames at 640x480 and 30 frames/s in a
# loop (90 frames along an arc of synth's lamp-and-sky room, 3 s; lpsynth://,
# capture/openni_driver; at each loop the camera jumps back to the arc's start and
# tracking relocalizes or loses it, as a hand would), reconstructing with live estimation on, for
# MINUTES; every 30 s the viewer's state (frames read and dropped, live estimates started
# and the shown one's index and state, resident memory) is written, and at the end a table
# and the verdict: no crash, memory flat within 10 % after the first minutes, frames
# dropped, estimates finished and their rate. Usage: scripts/soak-live.sh [MINUTES] [OUT]
# [SUMMARY OPTIONS] (default 30 minutes, out/soak; the options go to soak-summary.py).
# SOAK_INTERVAL (seconds between states, 30), SOAK_FRAMES (frames in the loop, 90) and
# SOAK_LIVE (the live switch's line, "live on": its keys as `estimate`'s) shorten it for
# the tests (tests/cli_soak.sh); SOAK_MIN_LIVE=N runs on past MINUTES until the N-th live
# estimate has its result (a count, not a rate: a loaded machine only takes longer). Needs a
# build (scripts/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
minutes="${1:-30}"
out="${2:-out/soak}"
shift $(( $# < 2 ? $# : 2 ))
interval="${SOAK_INTERVAL:-30}"
exe="${LIGHTPROBE_EXE:-./build/app/lightprobe}"
rm -rf "$out" && mkdir -p "$out"
# The frames the driver serves (it loops them); a device's 640x480.
"$exe" synth lamp-and-sky --frames "${SOAK_FRAMES:-90}" --width 640 --height 480 --spp 4 --depth-noise --out "$out/frames" >/dev/null
checks=$(python3 -c "import math,sys; print(max(1, math.ceil(float(sys.argv[1]) * 60 / float(sys.argv[2]))))" "$minutes" "$interval")
{
  echo "wait-open 60"
  echo "${SOAK_LIVE:-live on}"
  echo "reconstruct start"
  for k in $(seq 1 "$checks"); do
    echo "sleep $interval"
    echo "state $out/state-$(printf %03d "$k").json"
  done
  if [ -n "${SOAK_MIN_LIVE:-}" ]; then  # on a loaded machine: run on until that many have results
    echo "wait-live $SOAK_MIN_LIVE 900"
    echo "state $out/state-$(printf %03d $((checks + 1))).json"
  fi
  echo "quit"
} >"$out/script.txt"
frames=$(cd "$out/frames" && pwd)
run=("$exe" view "camera:lpsynth://$frames?fps=30" --script "$out/script.txt")
if [ -z "${DISPLAY:-}" ]; then run=(xvfb-run -a -s "-screen 0 1280x720x24" "${run[@]}"); fi
start=$(date +%s)
"${run[@]}" >"$out/viewer.log" 2>&1 || { tail -20 "$out/viewer.log"; echo "soak: the viewer failed"; exit 1; }
echo "soak: $minutes minutes run in $(( $(date +%s) - start )) s"
python3 scripts/soak-summary.py "$out" "$@"

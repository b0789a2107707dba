#!/usr/bin/env bash
# Issue 44's live targets on their protocol: a scan of at least 60 s played at 30 frames/s
# (`synth lamp-and-sky --frames 1800`: the demo's room and arc, 320x240, Kinect-like depth
# noise, rendered once into OUT/scan, ~17 min on 2 cores), run RUNS times through
# `--headless --live`, and one single estimate on the first run's finished scan. Prints, per
# run: when the first lights were written (after the first frame read), the longest wait
# between lights while the input played, the first lights (a preview's) and the last (the
# full estimate's) and the last estimate's end after the input ended, and the last lamp's
# error against the single estimate's.
# Usage: scripts/bench-live.sh [RUNS] [OUT]   (FRAMES=N for a shorter scan)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${LIGHTPROBE:-$root/build/app/lightprobe}
runs=${1:-3}
out=${2:-$root/out/bench-live}
frames=${FRAMES:-1800}
mkdir -p "$out"
if [ ! -e "$out/scan/truth.json" ]; then
  "$exe" synth lamp-and-sky --frames "$frames" --width 320 --height 240 --spp 16 --depth-noise --out "$out/scan"
fi
for i in $(seq 1 "$runs"); do
  rm -rf "$out/run$i"
  "$exe" --headless "$out/scan" --poses "$out/scan/trajectory.log" --out "$out/run$i" --live >"$out/run$i.log" 2>&1 ||
    { tail -5 "$out/run$i.log"; echo "bench-live: run $i failed" >&2; exit 1; }
done
rm -rf "$out/single"
"$exe" estimate "$out/run1/scene" --out "$out/single" --quiet >"$out/single.log" 2>&1 ||
  { tail -5 "$out/single.log"; echo "bench-live: the single estimate failed" >&2; exit 1; }
python3 - "$out" "$runs" <<'PY'
import csv, json, os, re, sys
out, runs = sys.argv[1], int(sys.argv[2])
single = json.load(open(os.path.join(out, "single", "report.json")))
print("| run | input (s) | estimates finished (cancelled) | first lights (s) | longest wait for lights while scanning (s) "
      "| first lights after the input (s) | last lights after the input (s) | last estimate's end after the input (s) "
      "| last lamp (share of its distance) |")
print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
for i in range(1, runs + 1):
    log = open(os.path.join(out, "run%d.log" % i)).read()
    ended = float(re.search(r"input ended after ([0-9.]+) s", log).group(1))
    rows = list(csv.DictReader(open(os.path.join(out, "run%d" % i, "live", "live.csv"))))
    lit = sorted(float(r["lights_s"]) for r in rows if r["lights_s"])
    done = [r for r in rows if r["error"] == ""]
    cancelled = sum(r["error"].startswith("cancelled") for r in rows)
    during = [t for t in lit if t <= ended]
    marks = [0.0] + during + [ended]
    wait = max(b - a for a, b in zip(marks, marks[1:]))
    last = done[-1]
    after = [t for t in lit if t > ended]
    print("| %d | %.1f | %d (%d) | %.1f | %.1f | %.1f | %.1f | %.1f | %.3f |" % (
        i, ended, len(done), cancelled, lit[0] if lit else float("nan"), wait,
        after[0] - ended if after else float("nan"), float(last["lights_s"]) - ended,
        float(last["finished_s"]) - ended, float(last["position_error_share"] or "nan")))
print("single estimate on run 1's scene: lights at %.1f s, the lamp %.3f of its distance" % (
    single["seconds"]["lights"], single["final"]["position_error_share"]))
PY

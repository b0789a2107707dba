#!/usr/bin/env bash
# Issue 41's measure for a change of the estimator: each scan's reconstructed bundle (what
# `lightprobe --headless SCAN --poses SCAN/trajectory.log --out RUN` wrote in RUN/scene)
# estimated under each variant's options over several seeds, each estimate scored by
# `lightprobe evaluate` against the scan's truth: the estimate's seconds (report.json's
# seconds.estimate), each true lamp's distance to the nearest estimate as a share of its
# distance from the room's centre, and the held-out view relit over the pixels the scan
# covers. One markdown row per scan, variant and seed, then each variant's means per scan.
# Usage: [SEEDS="1 2 3"] [LIGHTPROBE=build/app/lightprobe] scripts/bench-scans.sh \
#   "RUN1:SCAN1 RUN2:SCAN2" "name1=--opt value" "name2=--opt value" ... > table.md
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
lp=${LIGHTPROBE:-$root/build/app/lightprobe}
[ $# -ge 2 ] || { echo "usage: scripts/bench-scans.sh \"RUN:SCAN ...\" NAME=OPTIONS [NAME=OPTIONS ...]" >&2; exit 2; }
read -r -a pairs <<< "$1"
shift
variants=("$@")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "| scan | variant | seed | seconds | lamps (share of their distance) | held-out relit (covered) |"
echo "| --- | --- | --- | --- | --- | --- |"
for pair in "${pairs[@]}"; do
  run=${pair%%:*} scan=${pair#*:}
  [ -f "$run/scene/scene.json" ] || { echo "bench-scans: no bundle in $run/scene" >&2; exit 1; }
  [ -f "$scan/truth.json" ] || { echo "bench-scans: no truth.json in $scan" >&2; exit 1; }
  for v in "${variants[@]}"; do
    name=${v%%=*} opts=${v#*=}
    for seed in ${SEEDS:-1 2 3}; do
      d="$tmp/$name"
      rm -rf "$d" && mkdir -p "$d" && ln -s "$(cd "$run" && pwd)/scene" "$d/scene"
      # shellcheck disable=SC2086
      "$lp" estimate "$d/scene" --out "$d/estimate" --seed "$seed" --render-noise 0 --quiet $opts >/dev/null
      "$lp" evaluate "$d" --truth "$scan" >/dev/null
      python3 - "$d/estimate/report.json" "$d/evaluation.json" "$(basename "$scan")" "$name" "$seed" \
        >> "$tmp/rows" <<'PY'
import json, sys
report, ev = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
lamps = [l.get("error_share") for l in ev.get("lamps", [])]
held = ev.get("held_out_relit_covered")
print("\t".join([sys.argv[3], sys.argv[4], sys.argv[5], "%.1f" % report["seconds"]["estimate"],
                 " / ".join("%.1f %%" % (100 * s) for s in lamps if s is not None),
                 "%.3f" % held if held is not None else "-"]))
PY
      tail -1 "$tmp/rows" | awk -F'\t' '{printf "| %s | %s | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5, $6}'
    done
  done
done
echo
echo "| scan | variant | mean seconds | mean lamp share | mean held-out |"
echo "| --- | --- | --- | --- | --- |"
python3 - "$tmp/rows" <<'PY'
import sys, collections
groups = collections.OrderedDict()
for line in open(sys.argv[1]):
    scan, name, seed, sec, lamps, held = line.rstrip("\n").split("\t")
    g = groups.setdefault((scan, name), {"sec": [], "lamp": [], "held": []})
    g["sec"].append(float(sec))
    g["lamp"] += [float(x.split()[0]) for x in lamps.split(" / ") if x]
    if held != "-": g["held"].append(float(held))
mean = lambda v: sum(v) / len(v) if v else float("nan")
for (scan, name), g in groups.items():
    print("| %s | %s | %.1f | %.1f %% | %.3f |" % (scan, name, mean(g["sec"]), mean(g["lamp"]), mean(g["held"])))
PY

#!/usr/bin/env bash
# Estimate time side by side (issues 41, 42, 44: "within 1.3x of commit 69c3236, measured side
# by side"): each scene estimated by each binary given, alternating, REPEATS times (default 2);
# per binary the fastest estimate (report.json's seconds.estimate: the clean render left out),
# its rounds, the lamp's error against the truth where the scene has one (report.json's final
# position_error_m) and the fitted view's relative RMSE; then each binary's time over the
# first's. The binaries may be any builds (e.g. 69c3236 built in a worktree).
# Usage: [REPEATS=n] [SEED=s] [SCENES="cornerbox_one_light demo lamp-1m ... out/demo/scene"] \
#   scripts/bench-time.sh path/to/first/lightprobe path/to/second/lightprobe ... > table.md
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
[ $# -ge 1 ] || { echo "usage: scripts/bench-time.sh LIGHTPROBE [LIGHTPROBE ...]" >&2; exit 2; }
bins=("$@")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
source "$root/scripts/bench-scene.sh"
read -r -a names <<< "${SCENES:-cornerbox_one_light demo near-light lamp-0.5m lamp-1m lamp-2m lamp-4m two-lamps lamp-and-sky one-light sun-and-sky two-light}"
head="| scene |"; rule="| --- |"
for ((b = 0; b < ${#bins[@]}; ++b)); do
  head+=" binary $((b + 1)) s (rounds; lamp; fit) |"; rule+=" --- |"
  [ $b -gt 0 ] && { head+=" $((b + 1)) / 1 |"; rule+=" --- |"; }
done
echo "$head"; echo "$rule"
for s in "${names[@]}"; do
  k=${s//\//_}
  d=$(bench_scene "$s" "${bins[0]}" "$tmp")
  for ((i = 0; i < ${REPEATS:-2}; ++i)); do
    for ((b = 0; b < ${#bins[@]}; ++b)); do
      "${bins[$b]}" estimate "$d" --out "$tmp/o$b" --seed "${SEED:-1}" --quiet >/dev/null
      python3 - "$tmp/o$b/report.json" >> "$tmp/t$k.$b" <<'PY'
import json, sys
r = json.load(open(sys.argv[1])); f = r["final"]; p = f.get("position_error_m")
lamp = "-" if p in (None, "inf") else "%.1f cm" % (100 * p)
print(r["seconds"]["estimate"], len(r["rounds"]), lamp, "%.4f" % r["views"][0]["render_relative_rmse"])
PY
    done
  done
  python3 - "$s" "${#bins[@]}" "$tmp/t$k" <<'PY'
import sys
name, n, stem = sys.argv[1], int(sys.argv[2]), sys.argv[3]
best = []
for b in range(n):
    runs = [l.split() for l in open("%s.%d" % (stem, b))]
    best.append(min(runs, key=lambda r: float(r[0])))
cells = []
for b, r in enumerate(best):
    cells.append("%.2f (%s; %s; %s)" % (float(r[0]), r[1], r[2] + (" " + r[3] if r[2] != "-" else ""), r[-1]))
    if b > 0: cells.append("%.2f" % (float(r[0]) / float(best[0][0])))
print("| %s | %s |" % (name, " | ".join(cells)))
PY
done

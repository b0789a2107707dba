#!/usr/bin/env bash
# The glowing-surface search's cost and effect (issue 43; docs/benchmarks.md, session 31):
# each scene estimated with --emitters 0 and --emitters 1, alternating, REPEATS times (default
# 2); the fastest estimate of each (report.json's seconds.estimate), how many emitters the
# search kept, and whether the lamps and suns are the same. With OLD=path/to/an/older/lightprobe
# (the issue's commit 69c3236, built in a worktree), the same scenes by it too, in the same
# alternation, and the ratio of the default estimate's time to its.
# Usage: [REPEATS=n] [OLD=...] [SCENES="glow cornerbox_one_light demo lamp-1m ..."] scripts/bench-emitters.sh [path/to/lightprobe] > table.md
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/app/lightprobe}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
source "$root/scripts/bench-scene.sh"
read -r -a names <<< "${SCENES:-cornerbox_one_light glow demo lamp-1m two-lamps lamp-and-sky sun-and-sky lamp-4m}"
echo "| scene | --emitters 0 s | --emitters 1 s | ratio | emitters | lamps and suns | ${OLD:+older binary s | default / older |}"
echo "| --- | --- | --- | --- | --- | --- |${OLD:+ --- | --- |}"
for s in "${names[@]}"; do
  k=${s//\//_}  # (the scene's name in the temporary files' names)
  d=$(bench_scene "$s" "$exe" "$tmp")
  for ((i = 0; i < ${REPEATS:-2}; ++i)); do
    for e in 0 1; do
      "$exe" estimate "$d" --out "$tmp/o$e" --emitters $e --quiet >/dev/null
      python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["seconds"]["estimate"])' "$tmp/o$e/report.json" >> "$tmp/t$k$e"
    done
    if [ -n "${OLD:-}" ]; then
      "$OLD" estimate "$d" --out "$tmp/oo" --quiet >/dev/null
      python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["seconds"]["estimate"])' "$tmp/oo/report.json" >> "$tmp/t${k}o"
    fi
  done
  python3 - "$s" "$tmp/t${k}0" "$tmp/t${k}1" "$tmp/o0/lights.json" "$tmp/o1/lights.json" "$tmp/t${k}o" <<'PY'
import json, os, sys
s = sys.argv[1]
t0, t1 = (min(float(x) for x in open(f)) for f in sys.argv[2:4])
a, b = (json.load(open(f)) for f in sys.argv[4:6])
same = a["point_lights"] == b["point_lights"] and a["directional_lights"] == b["directional_lights"]
row = "| %s | %.2f | %.2f | %.2f | %d | %s |" % (s, t0, t1, t1 / t0, len(b.get("emitters", [])), "the same" if same else "differ")
if os.path.exists(sys.argv[6]):
    to = min(float(x) for x in open(sys.argv[6]))
    row += " %.2f | %.2f |" % (to, t1 / to)
print(row)
PY
done

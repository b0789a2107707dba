#!/usr/bin/env bash
# The glowing-surface search's cost and effect (issue 43; docs/benchmarks.md, session 31):
# each scene estimated with --emitters 0 and --emitters 1, alternating, REPEATS times (default
# 2); the fastest estimate of each (report.json's seconds.estimate), how many emitters the
# search kept, and whether the lamps and suns are the same.
# Usage: [REPEATS=n] [SCENES="glow cornerbox_one_light demo lamp-1m ..."] scripts/bench-emitters.sh [path/to/lightprobe] > table.md
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/app/lightprobe}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
read -r -a names <<< "${SCENES:-cornerbox_one_light glow demo lamp-1m two-lamps lamp-and-sky sun-and-sky lamp-4m}"
echo "| scene | --emitters 0 s | --emitters 1 s | ratio | emitters | lamps and suns |"
echo "| --- | --- | --- | --- | --- | --- |"
for s in "${names[@]}"; do
  case "$s" in
    cornerbox_one_light|glow) d="$root/tests/data/cycles/$s" ;;
    demo) d="$root/assets/demo" ;;
    *) "$exe" synth "$s" --out "$tmp/$s" >/dev/null; d="$tmp/$s" ;;
  esac
  for ((i = 0; i < ${REPEATS:-2}; ++i)); do
    for e in 0 1; do
      "$exe" estimate "$d" --out "$tmp/o$e" --emitters $e --quiet >/dev/null
      python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["seconds"]["estimate"])' "$tmp/o$e/report.json" >> "$tmp/t$s$e"
    done
  done
  python3 - "$s" "$tmp/t${s}0" "$tmp/t${s}1" "$tmp/o0/lights.json" "$tmp/o1/lights.json" <<'PY'
import json, sys
s = sys.argv[1]
t0, t1 = (min(float(x) for x in open(f)) for f in sys.argv[2:4])
a, b = (json.load(open(f)) for f in sys.argv[4:6])
same = a["point_lights"] == b["point_lights"] and a["directional_lights"] == b["directional_lights"]
print("| %s | %.2f | %.2f | %.2f | %d | %s |" % (s, t0, t1, t1 / t0, len(b.get("emitters", [])), "the same" if same else "differ"))
PY
done

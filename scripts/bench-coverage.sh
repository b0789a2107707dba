#!/usr/bin/env bash
# How often the true lights lie inside their 95 % regions (issue 42; docs/benchmarks.md): seven
# synthetic scenes x SEEDS scene seeds (synth --seed 100+k, estimate --seed k) and the Cycles
# cornerbox x SEEDS estimate seeds. Prints one line a true light (scene, seed, kind, error,
# squared Mahalanobis distance) and the count inside.
# Usage: [SEEDS=25] scripts/bench-coverage.sh [path/to/lightprobe] > coverage.txt
# (25 seeds: 200 estimates, about 25 minutes on 2 cores)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/app/lightprobe}
seeds=${SEEDS:-25}
# coverage-score.py needs numpy: Debian's python3 has it (install-deps.sh); a python3 earlier
# in PATH (pyenv) may not.
py=python3
python3 -c 'import numpy' 2>/dev/null || py=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scores=$tmp/scores.txt
: > "$scores"
for k in $(seq 1 "$seeds"); do
  for s in lamp-0.5m lamp-1m lamp-2m lamp-4m two-lamps lamp-and-sky sun-and-sky; do
    "$exe" synth "$s" --out "$tmp/scene" --seed $((100 + k)) > "$tmp/log" 2>&1 || { cat "$tmp/log" >&2; exit 1; }
    "$exe" estimate "$tmp/scene" --out "$tmp/est" --seed "$k" > "$tmp/log" 2>&1 || { cat "$tmp/log" >&2; exit 1; }
    "$py" "$root/scripts/coverage-score.py" "$tmp/scene/truth.json" "$tmp/est/lights.json" | sed "s/^/$s $k /" | tee -a "$scores"
    rm -rf "$tmp/scene" "$tmp/est"
  done
  cb=$root/tests/data/cycles/cornerbox_one_light
  "$exe" estimate "$cb" --out "$tmp/est" --seed "$k" > "$tmp/log" 2>&1 || { cat "$tmp/log" >&2; exit 1; }
  "$py" "$root/scripts/coverage-score.py" "$cb/truth.json" "$tmp/est/lights.json" | sed "s/^/cornerbox $k /" | tee -a "$scores"
  rm -rf "$tmp/est"
done
awk '{n++; if (($3 == "point" && $7 <= 7.81) || ($3 == "sun" && $7 <= 5.99)) k++}
     END {printf "%d of %d true lights inside their 95 %% regions (%.0f %%)\n", k, n, 100 * k / n}' "$scores"

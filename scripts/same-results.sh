#!/usr/bin/env bash
# Runs the estimates that a "no change of behaviour" refactor must leave as they were
# (docs/architecture.md, "Changing the estimator without changing its results"), fixed seeds:
# the Cycles cornerbox, synth lamp-0.5m, two-lamps and sun-and-sky, the demo recording's
# bundle (made by `scripts/demo.sh`; pass DEMO=path/to/scene to use one already made, or
# DEMO= to leave it out), and Cycles' sun (the directional light's whole fit).
# Writes OUT/NAME/{lights.json,convergence.csv,report.json}.
# Compare two such folders with scripts/compare-results.py.
# Usage: [DEMO=dir] [CASES="cornerbox lamp-0.5m ..."] scripts/same-results.sh OUT [path/to/lightprobe]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:?usage: same-results.sh OUT [lightprobe]}
exe=${2:-$root/build/app/lightprobe}
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
demo=${DEMO-$root/out/demo/scene}
read -r -a cases <<< "${CASES:-cornerbox lamp-0.5m two-lamps sun-and-sky demo cycles-sun}"
for c in "${cases[@]}"; do
  case "$c" in
    cornerbox) bundle="$root/tests/data/cycles/cornerbox_one_light" ;;
    cycles-sun) bundle="$root/tests/data/cycles/sun" ;;
    demo)
      [ -n "$demo" ] || continue
      [ -d "$demo" ] || { echo "same-results: no demo bundle at $demo (run scripts/demo.sh, or DEMO=)" >&2; exit 2; }
      bundle="$demo" ;;
    *) "$exe" synth "$c" --out "$tmp/$c" >/dev/null; bundle="$tmp/$c" ;;
  esac
  start=$SECONDS
  "$exe" estimate "$bundle" --out "$tmp/est-$c" --seed 1 --quiet >/dev/null
  mkdir -p "$out/$c"
  cp "$tmp/est-$c/lights.json" "$tmp/est-$c/convergence.csv" "$tmp/est-$c/report.json" "$out/$c/"
  echo "$c $((SECONDS - start)) s" >&2
done

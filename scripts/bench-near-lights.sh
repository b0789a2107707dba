#!/usr/bin/env bash
# The map alone against the map + point lights (docs/benchmarks.md, "Near lights"): each scene
# estimated with --point-lights 0 and then with the default, alternating, REPEATS times each
# (default 2), reading report.json: the time is each model's fastest run (the least
# disturbed on a shared machine), the fit and the lamp the last run's (same seed, same result).
# Usage: [REPEATS=n] [SCENES="cornerbox_one_light near-light ..."] scripts/bench-near-lights.sh [path/to/lightprobe] > table.md
# (SCENES: a subset of the default list, in its names; cornerbox_one_light is the Cycles bundle,
# demo the bundled far-light scene, the rest synth scenes)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/app/lightprobe}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
read -r -a names <<< "${SCENES:-cornerbox_one_light demo near-light lamp-0.5m lamp-1m lamp-2m lamp-4m two-lamps lamp-and-sky one-light sun-and-sky two-light}"
dirs=()
for s in "${names[@]}"; do
  case "$s" in
    cornerbox_one_light) dirs+=("$root/tests/data/cycles/cornerbox_one_light") ;;
    demo) dirs+=("$root/assets/demo") ;;
    *) "$exe" synth "$s" --out "$tmp/$s" >/dev/null; dirs+=("$tmp/$s") ;;
  esac
done
echo "| scene | K | total s | fitted | angle ° | point lights | radius m | lamp | time ratio |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
repeats=${REPEATS:-2}
for s in "${dirs[@]}"; do
  for ((i = 0; i < repeats; ++i)); do
    for k in 0 4; do
      alone=(); [ "$k" = 0 ] && alone=(--directional-lights 0)  # the map alone: no lamp, no sun
      "$exe" estimate "$s" --out "$tmp/out$k" --point-lights $k "${alone[@]}" --quiet >/dev/null
      python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["seconds"]["total"])' "$tmp/out$k/report.json" >> "$tmp/times$k"
    done
  done
  for k in 0 4; do
    python3 - "$tmp/out$k/report.json" "$(basename "$s")" "$k" "$tmp/t0" "$tmp/times$k" <<'PY'
import json, sys
r = json.load(open(sys.argv[1])); name, k, t0 = sys.argv[2], int(sys.argv[3]), sys.argv[4]
f = r["final"]; total = min(float(t) for t in open(sys.argv[5]))
lights = f.get("point_lights", [])
radius = ", ".join("%.3f" % l["radius"] for l in lights) or "—"
pos = f.get("position_error_m")
lamp = "—" if pos is None or pos == "inf" else "%.1f cm (%.1f %%)" % (100 * pos, 100 * f.get("position_error_share", float("nan")))
ratio = ""
if k == 0: open(t0, "w").write(str(total))
else: ratio = "%.2f" % (total / float(open(t0).read()))
print("| %s | %d | %.1f | %.4f | %.2f | %d | %s | %s | %s |" % (name if k == 0 else "", k, total,
      r["views"][0]["render_relative_rmse"], f.get("angular_error_deg", float("nan")), len(lights), radius, lamp, ratio))
PY
  done
  rm -f "$tmp/times0" "$tmp/times4"
done

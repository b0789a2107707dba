#!/usr/bin/env bash
# bench-report end to end on a small run: report.md, a PNG and a CSV per plot, the table.
set -eu
exe="$1"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" bench-report --quick --sizes 40x30 --scenes one-light sun-and-sky lamp-1m --synth-spp 16 --eval-spp 8 \
  --out "$out" >/dev/null
for m in fitted_rmse relit_error light_angle envmap_error; do
  for ext in png csv; do [ -s "$out/${m}_40x30.$ext" ] || { echo "missing ${m}_40x30.$ext"; exit 1; }; done
  head -c 8 "$out/${m}_40x30.png" | od -An -tx1 | grep -q "89 50 4e 47 0d 0a 1a 0a" || { echo "${m}: not a PNG"; exit 1; }
  head -1 "$out/${m}_40x30.csv" | grep -q "^scene,size,curve,setting,round,iteration,seconds,value" || exit 1
  grep -q "(${m}_40x30.png)" "$out/report.md" || { echo "report.md does not embed ${m}"; exit 1; }
done
# Every method has rows in the CSV behind plot (a), and the table has a row per scene.
for c in '"fast"' '"paper PGD"' '"FD Jacobian (extrapolated)"' '"fast: spp"' '"fast: rings"' '"fast: bounces"'; do
  grep -q "$c" "$out/fitted_rmse_40x30.csv" || { echo "no $c in fitted_rmse_40x30.csv"; exit 1; }
done
# The lamp scene: its position plot, the map alone beside the default, and the default's last
# position error (fast, per iteration) near the lamp (measured 1.4 cm at this tiny size).
for ext in png csv; do [ -s "$out/position_error_40x30.$ext" ] || { echo "missing position_error_40x30.$ext"; exit 1; }; done
grep -q '^lamp-1m,40x30,"fast, map alone"' "$out/fitted_rmse_40x30.csv" || { echo "no map-alone run on lamp-1m"; exit 1; }
grep -q '^one-light,.*"fast, map alone"' "$out/fitted_rmse_40x30.csv" && { echo "a map-alone run on a far scene"; exit 1; }
pos=$(grep '^lamp-1m,40x30,"fast",,' "$out/position_error_40x30.csv" | tail -1 | awk -F, '{print $8}')
. "$(dirname "$0")/check_number.sh"
check_below "lamp-1m position error (m)" "$pos" 0.05 || exit 1
for s in one-light sun-and-sky lamp-1m; do grep -q "^| $s | 40x30 |" "$out/report.md" || { echo "no table row for $s"; exit 1; }; done
# The map's prior: each weight the far scene's default estimate tried, one of them chosen.
for ext in png csv; do [ -s "$out/prior_40x30.$ext" ] || { echo "missing prior_40x30.$ext"; exit 1; }; done
grep -q "(prior_40x30.png)" "$out/report.md" || { echo "report.md does not embed the prior's plot"; exit 1; }
# (the map alone: four weights of the activation penalty, then three smooth maps at the
# weakest where that one scored best of the four, and only there)
[ "$(grep -c '^one-light,40x30,[^,]*,0,' "$out/prior_40x30.csv")" = 4 ] || { echo "one-light: not 4 weights tried"; exit 1; }
python3 - "$out/prior_40x30.csv" <<'PY' || exit 1
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["scene"] == "one-light"]
assert all(float(r["smooth"]) == 0 for r in rows if r["lights"] != "0"), "a smooth map beside a light"
rows = [r for r in rows if r["lights"] == "0"]  # the map alone
sparse = [r for r in rows if float(r["smooth"]) == 0]
smooth = [r for r in rows if float(r["smooth"]) > 0]
weakest_best = min(sparse, key=lambda r: float(r["heldout_loss"])) is min(sparse, key=lambda r: float(r["alpha"]))
assert len(smooth) == (3 if weakest_best else 0), ("smooth maps tried", len(smooth), "the weakest weight best", weakest_best)
assert len({float(r["alpha"]) for r in smooth}) <= 1 and all(float(r["alpha"]) == min(float(q["alpha"]) for q in sparse) for r in smooth)
PY
[ "$(grep -c '^one-light,40x30,.*,1$' "$out/prior_40x30.csv")" = 1 ] || { echo "one-light: not one weight chosen"; exit 1; }
# lamp-1m: each weight with the lamp, and the lamp kept.
# (beside a lamp no smooth map is tried)
[ "$(grep -c '^lamp-1m,40x30,[^,]*,0,1,' "$out/prior_40x30.csv")" = 4 ] || { echo "lamp-1m: not 4 weights tried"; exit 1; }
[ "$(grep -c '^lamp-1m,40x30,' "$out/prior_40x30.csv")" = 4 ] || { echo "lamp-1m: a smooth map tried beside the lamp"; exit 1; }
grep -q '^lamp-1m,40x30,[^,]*,0,1,.*,1$' "$out/prior_40x30.csv" || { echo "lamp-1m: the lamp was not kept"; exit 1; }
echo "bench-report ok"

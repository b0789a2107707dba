#!/usr/bin/env bash
# A sun from the command line (issue 21): `estimate` on synth's sun-and-sky (96 x 72) with the
# defaults' directional lights writes one in lights.json within half a degree of truth.json's
# sun, its irradiance within 10 % (2 bounces here), and report.json's "why" line for it and its
# model naming it; with
# `--directional-lights 0` it writes none and the map takes the sun. (The sky beside the sun,
# 0.1 % of the light, is checked on Cycles' sun in cycles_test: here it is below the noise.) The estimate's lights.json then relights the bundle by `render --lights`.
set -eu
exe="$1"
. "$(dirname "$0")/check_number.sh"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$exe" synth sun-and-sky --out "$tmp/s" --width 96 --height 72 --spp 64 >/dev/null
small=(--rings 13 --spp 16 --bounces 2 --max-rounds 2 --quiet)
"$exe" estimate "$tmp/s" --out "$tmp/on" "${small[@]}" >/dev/null
"$exe" estimate "$tmp/s" --out "$tmp/off" "${small[@]}" --directional-lights 0 >/dev/null
read -r suns angle ratio why suns_off env_off < <(python3 - "$tmp" <<'PY'
import json, math, os, sys
t = sys.argv[1]
truth = json.load(open(t + "/s/truth.json"))["lights"][0]
d = truth["direction"]
on, off = (json.load(open(t + "/" + k + "/lights.json")) for k in ("on", "off"))
report = json.load(open(t + "/on/report.json"))
suns = on["directional_lights"]
angle = ratio = "none"
if suns:
    a = suns[0]["direction"]
    angle = math.degrees(math.acos(max(-1.0, min(1.0, sum(x * y for x, y in zip(a, d))))))
    # The sun's irradiance facing it: its power over the sphere of its distance.
    e = truth["rgb_power"][0] / (4 * math.pi * truth["distance"] ** 2)
    ratio = suns[0]["irradiance"][0] / e
why = sum("directional light" in c and "kept" in c for c in json.dumps(report).split("\""))
env_off = int(bool(off.get("environment")) and os.path.exists(t + "/off/" + off["environment"]))
# report.json's model names what it kept: the sun (and no lamp here).
chosen = report["model"]["chosen"]
assert chosen.endswith(" + %d directional light(s)" % len(suns)) or not suns, chosen
print(len(suns), angle, ratio, why, len(off["directional_lights"]), env_off)
PY
)
[ "$suns" = 1 ] || { echo "expected one directional light, got $suns"; exit 1; }
check_below "the sun's direction, degrees from the truth" "$angle" 0.5
check_between "the sun's irradiance over the truth's (measured 1.04)" "$ratio" 0.9 1.1
[ "$why" -ge 1 ] || { echo "report.json says nothing of the directional light kept"; exit 1; }
[ "$suns_off" = 0 ] || { echo "--directional-lights 0 still wrote $suns_off directional light(s)"; exit 1; }
[ "$env_off" = 1 ] || { echo "--directional-lights 0: the map does not hold the sun"; exit 1; }
err=$("$exe" render "$tmp/s" --lights "$tmp/on/lights.json" --out "$tmp/relit" --spp 64 |
  sed -n 's/.*relative RMSE against the bundle.s image \([0-9.eE+-]*\).*/\1/p' | head -1)
check_below "the estimate's lights.json relit against the image" "$err" 0.1
echo "cli_sun: sun $angle degrees off, irradiance ratio $ratio, relit $err"

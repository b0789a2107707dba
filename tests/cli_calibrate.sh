#!/usr/bin/env bash
# Calibration from the command line through the real OpenNI2 stack: the synthetic device
# serves a static scene and, like a camera, scales its light with the manual exposure;
# `calibrate response --device` captures the bracket and must find the sRGB curve the
# frames were encoded with. Then the file drives reconstruct; bad input is one line, exit 2.
set -eu
exe="$1"
. "$(dirname "$0")/check_number.sh"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$exe" synth one-light --frames 1 --width 160 --height 120 --spp 16 --out "$out/static" >/dev/null
"$exe" calibrate response --device --source "lpsynth://$out/static" --size 160x120 --exposures 25 50 100 200 400 \
  --out "$out/cal.json" >"$out/log"
diff=$(sed -n 's/.*differs from sRGB by \([0-9.]*\) %.*/\1/p' "$out/log")
check_below "response's difference from sRGB (%)" "$diff" 1 || { cat "$out/log"; exit 1; }
grep -q '"format": "lightprobe-calibration"' "$out/cal.json"
grep -q "mitsunaga-nayar" "$out/cal.json"

# The calibration drives reconstruction (and says so).
"$exe" synth one-light --frames 24 --width 160 --height 120 --spp 4 --out "$out/frames" >/dev/null
"$exe" reconstruct "$out/frames" --calibration "$out/cal.json" --keyframes 1 --out "$out/scene" >"$out/rlog" 2>&1
grep -q "^calibrated: response (Mitsunaga-Nayar)" "$out/rlog" || { cat "$out/rlog"; exit 1; }
"$exe" reconstruct "$out/frames" --keyframes 1 --out "$out/scene2" 2>&1 | grep -q "^uncalibrated: assuming an sRGB response"
# The bundle keeps the calibration it was linearized with; keyframes already corrected for
# vignetting cannot measure it (a bad-input case below).
grep -q mitsunaga "$out/scene/calibration.json" ||
  { echo "scene/calibration.json does not hold the applied calibration"; ls "$out/scene"; exit 1; }
sed 's/"format": "lightprobe-calibration",/"format": "lightprobe-calibration", "vignetting": {"model": "kim-pollefeys", "a": -0.3, "b": 0, "c": 0},/' \
  "$out/cal.json" >"$out/calv.json"
grep -q kim-pollefeys "$out/calv.json" || { echo "could not add vignetting to the calibration"; exit 1; }
"$exe" reconstruct "$out/frames" --calibration "$out/calv.json" --keyframes 2 --out "$out/scenev" >/dev/null 2>&1
set +e; "$exe" calibrate vignetting --scene "$out/scenev" --out "$out/v.json" >"$out/vlog" 2>&1; set -e
grep -q "already corrected for vignetting" "$out/vlog" || { echo "vignetting from corrected keyframes:"; cat "$out/vlog"; exit 1; }

# Bad input.
echo '{"format": "lightprobe-calibration", "version": 7}' >"$out/bad.json"
for args in "reconstruct $out/frames --calibration $out/bad.json --out $out/x" \
            "calibrate geometry $out/frames/color/00000.png $out/frames/color/00001.png $out/frames/color/00002.png --out $out/x.json" \
            "calibrate response $out/frames/color/00000.png --exposures 1 --out $out/x.json" \
            "calibrate vignetting $out/missing.png --out $out/x.json" \
            "calibrate vignetting --scene $out/scenev --out $out/x.json"; do
  set +e; "$exe" $args >"$out/bad" 2>&1; rc=$?; set -e
  [ "$rc" -eq 2 ] || { echo "$args: exit $rc"; cat "$out/bad"; exit 1; }
  [ "$(grep -c . "$out/bad" | tr -d ' ')" -le 2 ] || { echo "$args: more than one error line"; cat "$out/bad"; exit 1; }
  [ ! -e "$out/x" ] && [ ! -e "$out/x.json" ] || { echo "$args wrote output"; exit 1; }
done
echo "calibrate ok: response differs from sRGB by $diff %"

#!/usr/bin/env bash
# The live soak (scripts/soak-live.sh), short: the window on the project's OpenNI2 driver
# at 30 frames/s (640x480, 30 frames looped) with live estimation on (light settings) for
# 1.5 minutes, and on until 2 live estimates have their results (a loaded machine finished
# only 1 in 1.5 minutes): no crash, at least 2 finished, resident memory under 4 GiB.
# Counts, not rates (the 30-minute run and its rates: docs/benchmarks.md).
set -eu
exe="$1"; src="$2"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
cd "$src"
LIGHTPROBE_EXE="$exe" SOAK_INTERVAL=15 SOAK_FRAMES=30 SOAK_MIN_LIVE=2 \
  SOAK_LIVE="live on rings=13 spp=16 bounces=2 rounds=2 point-lights=1 trace-pixels=2 albedo-passes=1 render-noise=0.2" \
  bash scripts/soak-live.sh 1.5 "$out/soak" --min-finished 2 --max-growth 1 --max-mb 4096

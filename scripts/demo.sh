#!/usr/bin/env bash
# Quick start 1: install what is missing, build, and estimate the lighting of the
# bundled demo scene (assets/demo, a synthetic room lit by one light). No camera needed.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
out="${1:-out/demo}"
./build/app/lightprobe estimate assets/demo --out "$out"

#!/usr/bin/env bash
# Quick start 1: install what is missing, build, and run the main job on the bundled demo
# recording (assets/demo-recording/demo.oni: a synthetic room lit by a lamp 1.5 m away and a
# dim sky, recorded through OpenNI2): reconstruct the scene from the RGB-D frames, then estimate its
# lighting. No camera needed. The given poses only fix the world frame for the ground
# truth (tracking still runs); results in out/demo/scene and out/demo/estimate.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
out="${1:-out/demo}"
demo=assets/demo-recording
./build/app/lightprobe --headless "$demo/demo.oni" --poses "$demo/trajectory.log" --out "$out"

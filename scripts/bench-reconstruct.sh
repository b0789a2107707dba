#!/usr/bin/env bash
# Reconstruction frames/s side by side (issue 44: "at 640x480 >= 30 frames/s with the defaults
# and nothing else running, >= 20 while a live estimate runs beside it"): `bench --parts
# reconstruct` by each binary given, alternating, REPEATS times (default 3); per binary and
# image size the median frames/s of the default run (every frame tracked, every second fused),
# its stages and trajectory error. BESIDE=1 runs an estimate beside it the whole time (the demo
# bundle estimated over and over at nice 10, as the viewer's background estimator runs), so
# the figures are those of reconstruction sharing the machine with a live estimate.
# Usage: [REPEATS=n] [BESIDE=1] scripts/bench-reconstruct.sh LIGHTPROBE [LIGHTPROBE ...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
[ $# -ge 1 ] || { echo "usage: scripts/bench-reconstruct.sh LIGHTPROBE [LIGHTPROBE ...]" >&2; exit 2; }
bins=("$@")
tmp=$(mktemp -d)
beside=""
cleanup() {
  [ -n "$beside" ] && kill "$beside" 2>/dev/null && wait "$beside" 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT
if [ "${BESIDE:-0}" = 1 ]; then
  (while :; do nice -n 10 "${bins[0]}" estimate "$root/assets/demo" --out "$tmp/beside" --quiet >/dev/null 2>&1 || true; done) &
  beside=$!
  sleep 3  # the estimate under way
fi
for ((i = 0; i < ${REPEATS:-3}; ++i)); do
  for ((b = 0; b < ${#bins[@]}; ++b)); do
    "${bins[$b]}" bench --parts reconstruct --out "$tmp/r$b.$i" >/dev/null 2>&1
  done
done
python3 - "$tmp" "${#bins[@]}" "${REPEATS:-3}" "$@" <<'PY'
import re, statistics, sys
tmp, nb, reps, bins = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:]
print("| binary | size | frames/s (median of %d) | each run | preprocess / track / fuse / raycast ms | ATE mm |" % reps)
print("| --- | --- | --- | --- | --- | --- |")
for b in range(nb):
    rows = {}
    for i in range(reps):
        for line in open(f"{tmp}/r{b}.{i}/bench.md"):
            if "fusing every second frame" not in line:
                continue
            size = line.split("|")[1].strip()
            m = re.search(r"([\d.]+) frames/s; per frame ([\d.]+) ms preprocess, ([\d.]+) ms track, ([\d.]+) ms fuse, "
                          r"([\d.]+) ms raycast.*ATE ([\d.]+) mm", line)
            rows.setdefault(size, []).append([float(x) for x in m.groups()])
    for size, runs in rows.items():
        fps = [r[0] for r in runs]
        med = sorted(runs, key=lambda r: r[0])[len(runs) // 2]
        print(f"| {bins[b]} | {size} | {statistics.median(fps):.1f} | {', '.join(f'{f:.1f}' for f in fps)} | "
              f"{med[1]:.1f} / {med[2]:.1f} / {med[3]:.1f} / {med[4]:.1f} | {med[5]:.1f} |")
PY

#!/usr/bin/env bash
# Directional lights (docs/benchmarks.md, issue 21): each scene estimated with
# --directional-lights 0 and 1, alternating, REPEATS times each (default 2; the time is each
# model's fastest run), on the fitted view of a `synth --held-out 1` bundle; the estimate's
# lights.json then relights the held-out view (`render --lights`, 256 spp), whose relative
# RMSE is the held-out error. Usage: [REPEATS=n] [SCENES="sun-and-sky ..."] scripts/bench-directional.sh [lightprobe] > table.md
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/app/lightprobe}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
read -r -a scenes <<< "${SCENES:-sun-and-sky one-light two-light env-studio env-sunset lamp-1m lamp-and-sky two-lamps near-light}"
repeats=${REPEATS:-2}
echo "| scene | directional | total s | fitted | held-out | angle ° | suns | sun ° off | lamps | time ratio |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
for s in "${scenes[@]}"; do
  "$exe" synth "$s" --held-out 1 --out "$tmp/$s" >/dev/null
  # The fitted bundle (view 0) and the held-out one (view 1), same mesh and images.
  python3 - "$tmp/$s" <<'PY'
import json, os, sys
d = sys.argv[1]; s = json.load(open(os.path.join(d, "scene.json")))
for name, k in (("fit", 0), ("held", 1)):
    os.makedirs(os.path.join(d, name), exist_ok=True)
    t = dict(s); v = dict(s["views"][k])
    for key in ("image", "mask"):
        if key in v: v[key] = os.path.join("..", v[key])
    t["mesh"] = os.path.join("..", s["mesh"]); t["views"] = [v]
    json.dump(t, open(os.path.join(d, name, "scene.json"), "w"))
    if name == "fit" and os.path.exists(os.path.join(d, "truth.json")):
        os.symlink(os.path.join("..", "truth.json"), os.path.join(d, name, "truth.json"))
PY
  for ((i = 0; i < repeats; ++i)); do
    for k in 0 1; do
      "$exe" estimate "$tmp/$s/fit" --out "$tmp/out$k" --directional-lights $k --quiet >/dev/null
      python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["seconds"]["total"])' "$tmp/out$k/report.json" >> "$tmp/times$k"
    done
  done
  for k in 0 1; do
    held=$("$exe" render "$tmp/$s/held" --lights "$tmp/out$k/lights.json" --out "$tmp/relit$k" --spp 256 |
      sed -n 's/.*relative RMSE against the bundle.s image \([0-9.eE+-]*\).*/\1/p' | head -1)
    python3 - "$tmp/out$k/report.json" "$s" "$k" "$tmp/t0" "$tmp/times$k" "$held" "$tmp/$s/truth.json" <<'PY'
import json, math, sys
r = json.load(open(sys.argv[1])); name, k, t0 = sys.argv[2], int(sys.argv[3]), sys.argv[4]
total = min(float(t) for t in open(sys.argv[5])); held = sys.argv[6]
f = r["final"]; suns = f.get("directional_lights", []); lamps = f.get("point_lights", [])
off = "—"
try:
    t = json.load(open(sys.argv[7]))
    sun = [l for l in t.get("lights", []) if l.get("type") == "sun"]
    if suns and sun:
        a, b = suns[0]["direction"], sun[0]["direction"]
        off = "%.2f" % math.degrees(math.acos(max(-1, min(1, sum(x * y for x, y in zip(a, b))))))
except Exception:
    pass
ratio = ""
if k == 0: open(t0, "w").write(str(total))
else: ratio = "%.2f" % (total / float(open(t0).read()))
print("| %s | %d | %.1f | %.4f | %s | %.2f | %d | %s | %d | %s |" % (name if k == 0 else "", k, total,
      r["views"][0]["render_relative_rmse"], held or "?", f.get("angular_error_deg", float("nan")), len(suns), off,
      len(lamps), ratio))
PY
  done
  rm -f "$tmp/times0" "$tmp/times1"
done

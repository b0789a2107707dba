#!/usr/bin/env python3
"""Summarises a soak's state files (scripts/soak-live.sh): a table over time and the
verdict. Exit 1 when memory grew more than --max-growth (0.10) after the first fifth of the
run (at least the first minute), when resident memory ever passed --max-mb (none), when
fewer than --min-finished (1) live estimates finished, or when no frame was read over the
last two intervals (a stalled reconstruction).

Growth is a trend, not a swing: each live estimate's working set (a few hundred MiB) comes
and goes, so a sample taken during one is higher than one taken between two. The samples
after the first minutes are split in halves and the later half's highest is compared with
the earlier half's highest: a leak raises both the floor and the peaks, an estimate's working
set does not. The swing (highest over lowest after the first minutes) is reported beside it."""
import argparse
import glob
import json
import os
import sys

parser = argparse.ArgumentParser()
parser.add_argument("out")
parser.add_argument("--min-finished", type=int, default=1)
parser.add_argument("--max-growth", type=float, default=0.10)
parser.add_argument("--max-mb", type=float, default=float("inf"))
args = parser.parse_args()
out = args.out
states = [json.load(open(f)) for f in sorted(glob.glob(os.path.join(out, "state-*.json")))]
if not states:
    sys.exit("soak: no state written")


def finished(s):
    e = s["estimate"]
    if not e.get("live"):
        return 0
    own = e["has_result"] if "has_result" in e else e["state"] == "done"  # (its own result, refining or not)
    return e["live_index"] if own else e["live_index"] - 1


print("| seconds | frames read | dropped | live estimates started | finished | resident MiB |")
print("| --- | --- | --- | --- | --- | --- |")
for s in states:
    print("| %.0f | %d | %d | %d | %d | %.0f |" % (s["seconds"], s["frames_read"], s["dropped"],
                                               s["live_estimates"], finished(s), s["rss_mb"]))
last = states[-1]
settle = max(60.0, 0.2 * last["seconds"])
after = [s for s in states if s["seconds"] >= settle] or [last]
half = max(1, len(after) // 2)
earlier, later = after[:half], after[half:] or after[-1:]
base = max(s["rss_mb"] for s in earlier)
peak = max(s["rss_mb"] for s in later)
growth = peak / base - 1 if base > 0 else float("nan")
low = min(s["rss_mb"] for s in after)
done = finished(last)
minutes = last["seconds"] / 60
print("soak: %.1f minutes, %d frames read, %d dropped (%.1f %%), %d live estimates finished (%.2f a minute), "
      "resident at most %.0f MiB from %.0f s to %.0f s and %.0f MiB after (%+.1f %%); swing %.0f-%.0f MiB"
      % (minutes, last["frames_read"], last["dropped"], 100.0 * last["dropped"] / max(1, last["frames_read"] + last["dropped"]),
         done, done / max(minutes, 1e-9), base, earlier[0]["seconds"], earlier[-1]["seconds"], peak, 100 * growth,
         low, max(base, peak)))
most = max(s["rss_mb"] for s in states)
problems = []
if done < args.min_finished:
    problems.append("%d live estimates finished, fewer than %d" % (done, args.min_finished))
if not growth <= args.max_growth:
    problems.append("memory grew %.1f %% after the first minutes (at most %.0f %%)" % (100 * growth, 100 * args.max_growth))
if len(states) >= 3 and not states[-1]["frames_read"] > states[-3]["frames_read"]:
    problems.append("no frame read from %.0f s on (the reconstruction stalled)" % states[-3]["seconds"])
if most > args.max_mb:
    problems.append("resident memory reached %.0f MiB (at most %.0f)" % (most, args.max_mb))
print("soak: " + ("passed" if not problems else "FAILED: " + "; ".join(problems)))
ok = not problems
sys.exit(0 if ok else 1)

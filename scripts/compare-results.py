#!/usr/bin/env python3
"""Compares two folders written by scripts/same-results.sh: every case's lights.json,
convergence.csv and report.json must hold the same decisions (keys, strings, counts, the
rows of the convergence log) and the same numbers within a relative tolerance (default
1e-6), leaving out what measures time or the machine (keys and columns naming seconds,
time, threads, wall), the bundle's path ("scene") and the clean render's passes. Prints each difference and exits 1 when there is any.
Usage: compare-results.py A B [--rtol 1e-6]"""
import argparse, csv, json, math, os, sys

SKIP = ("second", "time", "thread", "wall", "hardware")
SKIP_KEYS = ("scene", "clean_render")  # the bundle's path; the clean render's passes (as many as its time allows)


def skipped(key):
    k = str(key).lower()
    return k in SKIP_KEYS or any(s in k for s in SKIP)


def close(a, b, rtol):
    if a == b:
        return True
    if isinstance(a, float) and math.isnan(a) and isinstance(b, float) and math.isnan(b):
        return True
    return abs(a - b) <= rtol * max(abs(a), abs(b)) + 1e-12


def compare(a, b, path, rtol, out):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if skipped(k):
                continue
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'B' if k not in a else 'A'}")
                continue
            compare(a[k], b[k], f"{path}.{k}", rtol, out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: {len(a)} items against {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            compare(x, y, f"{path}[{i}]", rtol, out)
    elif isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or isinstance(b, str) or a is None or b is None:
        if a != b:
            out.append(f"{path}: {a!r} against {b!r}")
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if not close(float(a), float(b), rtol):
            out.append(f"{path}: {a!r} against {b!r} (relative {abs(a - b) / max(abs(a), abs(b)):.2e})")
    elif type(a) != type(b) or a != b:
        out.append(f"{path}: {a!r} against {b!r}")


def number(s):
    try:
        return float(s)
    except ValueError:
        return s


def load_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = rows[0]
    return [{h: number(v) for h, v in zip(head, r)} for r in rows[1:]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--rtol", type=float, default=1e-6)
    args = ap.parse_args()
    cases = sorted(set(os.listdir(args.a)) | set(os.listdir(args.b)))
    total = 0
    for case in cases:
        diffs = []
        for name in ("lights.json", "report.json", "convergence.csv"):
            pa, pb = os.path.join(args.a, case, name), os.path.join(args.b, case, name)
            if not (os.path.exists(pa) and os.path.exists(pb)):
                diffs.append(f"{name}: missing in {'A' if not os.path.exists(pa) else 'B'}")
                continue
            if name.endswith(".json"):
                compare(json.load(open(pa)), json.load(open(pb)), name, args.rtol, diffs)
            else:
                compare(load_csv(pa), load_csv(pb), name, args.rtol, diffs)
        total += len(diffs)
        print(f"{case}: {'same' if not diffs else f'{len(diffs)} differences'}")
        for d in diffs[:40]:
            print("  " + d)
    sys.exit(1 if total else 0)


if __name__ == "__main__":
    main()

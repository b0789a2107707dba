#!/usr/bin/python3
"""A small copy of a Cycles RGB-D scan for the tests: the first FRAMES frames at half size.

Colour: each 2x2 block averaged in linear light (the sRGB curve undone, averaged, encoded
again to 8 bits), so one image unit stays one unit of Cycles radiance. Depth: a 2x2
block's mean where its four samples are valid and within 3 % of each other, else 0 (no
depth across an edge). The pixel centre of the new (i, j) is the old (2i + 0.5, 2j + 0.5):
fx/2, fy/2, cx' = (cx - 0.5)/2, cy' = (cy - 0.5)/2. trajectory.log keeps its first FRAMES
poses; truth.json, gt_mesh.ply and holdout/ (already 320x240) are copied as they are.

Usage: /usr/bin/python3 scripts/make-test-scan.py SCAN OUT [FRAMES]
(needs Debian's python3-numpy and python3-pil; not needed to build or test)
"""
import json
import shutil
import sys
from pathlib import Path

import numpy as np
from PIL import Image


def srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(c, 0, 1)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def half_colour(path):
    rgb = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255
    lin = srgb_to_linear(rgb)
    h, w = lin.shape[0] // 2, lin.shape[1] // 2
    lin = lin[: 2 * h, : 2 * w].reshape(h, 2, w, 2, 3).mean(axis=(1, 3))
    return Image.fromarray(np.round(255 * linear_to_srgb(lin)).astype(np.uint8), "RGB")


def half_depth(path):
    d = np.asarray(Image.open(path), dtype=np.float64)
    h, w = d.shape[0] // 2, d.shape[1] // 2
    blocks = d[: 2 * h, : 2 * w].reshape(h, 2, w, 2).transpose(0, 2, 1, 3).reshape(h, w, 4)
    lo, hi = blocks.min(axis=2), blocks.max(axis=2)
    keep = (lo > 0) & (hi - lo <= 0.03 * lo)
    out = np.where(keep, np.round(blocks.mean(axis=2)), 0).astype(np.uint16)
    return Image.fromarray(out)


def main():
    scan, out = Path(sys.argv[1]), Path(sys.argv[2])
    frames = int(sys.argv[3]) if len(sys.argv) > 3 else 20
    (out / "color").mkdir(parents=True, exist_ok=True)
    (out / "depth").mkdir(parents=True, exist_ok=True)
    names = sorted(p.name for p in (scan / "color").glob("*.png"))[:frames]
    for name in names:
        half_colour(scan / "color" / name).save(out / "color" / name, optimize=True)
        half_depth(scan / "depth" / name).save(out / "depth" / name, optimize=True)
    k = json.loads((scan / "intrinsics.json").read_text())
    small = {"width": k["width"] // 2, "height": k["height"] // 2, "fx": k["fx"] / 2, "fy": k["fy"] / 2,
             "cx": (k["cx"] - 0.5) / 2, "cy": (k["cy"] - 0.5) / 2}
    (out / "intrinsics.json").write_text(json.dumps(small, indent=2) + "\n")
    lines = (scan / "trajectory.log").read_text().splitlines()
    (out / "trajectory.log").write_text("\n".join(lines[: 5 * len(names)]) + "\n")
    shutil.copy(scan / "truth.json", out / "truth.json")
    shutil.copy(scan / "gt_mesh.ply", out / "gt_mesh.ply")
    (out / "holdout").mkdir(exist_ok=True)
    for f in ("holdout.json", "holdout.exr", "albedo.exr", "depth.exr", "mask.png"):
        shutil.copy(scan / "holdout" / f, out / "holdout" / f)
    print(f"{len(names)} frames of {scan} at {small['width']}x{small['height']} in {out}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
# Each true light's squared Mahalanobis distance to its nearest estimate of its kind under the
# estimate's covariance (docs/formats.md: a point light's position_covariance, a directional
# light's direction_covariance in its tangent plane); inside the 95 % region at <= 7.81 (a
# position) or <= 5.99 (a direction). One line a true light: KIND ERROR m2 VALUE.
# Usage: scripts/coverage-score.py TRUTH.json LIGHTS.json   (truth.json of `lightprobe synth` or
# of a Cycles bundle in tests/data/cycles; lights.json of `lightprobe estimate`)
import json
import math
import sys

import numpy as np

truth = json.load(open(sys.argv[1]))
est = json.load(open(sys.argv[2]))
for tl in truth["lights"]:
    if tl["type"] in ("sphere", "point"):
        p = np.array(tl["position"])
        if not est["point_lights"]:
            print("point MISSING")
            continue
        l = min(est["point_lights"], key=lambda l: np.linalg.norm(np.array(l["position"]) - p))
        d = np.array(l["position"]) - p
        cov = l.get("position_covariance")
        m2 = float(d @ np.linalg.pinv(np.array(cov, dtype=float)) @ d) if cov else float("inf")
        print("point %.2f cm m2 %.2f" % (100 * np.linalg.norm(d), m2))
    else:
        u = np.array(tl["direction"], dtype=float)
        u /= np.linalg.norm(u)
        if not est["directional_lights"]:
            print("sun MISSING")
            continue
        l = max(est["directional_lights"], key=lambda l: np.dot(l["direction"], u))
        v = np.array(l["direction"], dtype=float)
        angle = math.acos(min(1.0, float(np.dot(u, v))))
        d = u - v * np.dot(u, v)
        d = d / max(np.linalg.norm(d), 1e-12) * angle
        cov = l.get("direction_covariance")
        m2 = float(d @ np.linalg.pinv(np.array(cov, dtype=float)) @ d) if cov else float("inf")
        print("sun %.3f deg m2 %.2f" % (math.degrees(angle), m2))

"""Baseline for bench_measure.py: the measure R with a plain per-point, per-ray Python loop.

Same semantics as island_mapping.core.measure (module docstring there), written the obvious way:
for each point, for each ray, one call of the brute-force ray caster for that single ray, then
per-segment sums in a dict. Kept only as the reference the vectorized version is timed against.
"""

from __future__ import annotations

import math

import numpy as np
from island_mapping.core.measure import MeasureConfig
from island_msgs_py.raycast import raycast


def baseline_r(segments: np.ndarray, x: float, y: float, cfg: MeasureConfig) -> float:
    """r = F (1 + Q) / 2 at (x, y) [m] (eps = 0), one ray at a time."""
    n_rays = max(1, round(360.0 / cfg.angular_res_deg))
    dtheta = math.radians(cfg.angular_res_deg)
    cos_min = math.cos(math.radians(cfg.reflect_deg)) - 1e-12
    strength: dict[int, float] = {}
    origin = np.array([[x, y]])
    for j in range(n_rays):
        hit = raycast(segments, origin, np.array([j * dtheta]), cfg.max_range_m)
        i = int(hit.segment[0])
        if i < 0 or hit.distance_m[0] > cfg.max_range_m or hit.cos_incidence[0] < cos_min:
            continue
        w = math.exp(-cfg.k * float(hit.distance_m[0])) * float(hit.cos_incidence[0]) * dtheta
        strength[i] = strength.get(i, 0.0) + w
    if not strength:
        return 0.0
    normals = {}
    for i in strength:
        x1, y1, x2, y2 = segments[i]
        length = math.hypot(x2 - x1, y2 - y1)
        normals[i] = (-(y2 - y1) / length, (x2 - x1) / length)
    ref = max(sorted(strength), key=lambda i: strength[i])
    rx, ry = normals[ref]
    c_par = c_perp = 0.0
    for i, s in strength.items():
        nx, ny = normals[i]
        c_par += s * abs(rx * nx + ry * ny)
        c_perp += s * abs(rx * ny - ry * nx)

    def filt(c: float) -> float:
        return 0.0 if c <= 0 else 1.0 / (1.0 + (cfg.c / c) ** cfg.m)

    a, b = filt(c_par), filt(c_perp)
    lo, hi = min(a, b), max(a, b)
    q = lo / hi if hi > 0 else 0.0
    return lo * (1.0 + q) / 2.0

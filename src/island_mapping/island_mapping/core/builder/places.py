"""The correlative place search: a recognition strategy for a robot that has lost its islands
(passive mode, `PassiveConfig.place_recognition`): where could a scan be in an island? The
island's line model as a distance field is searched over positions within the coverage radius
and all headings (brute force); the best score must beat the best distinct hypothesis by a
margin, so a corridor (which fits anywhere along itself) is refused."""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.geometry import wrap_angles
from island_msgs_py.types import FloatArray, LineModel

# Correlative place search: distance-field resolution [m], search grid over the coverage
# square [m] and headings [deg], points used (every k-th), and the score's distance scale [m].
_FIELD_RES_M = 0.1
_SEARCH_STEP_M = 0.2
_SEARCH_STEP_DEG = 10.0
_SEARCH_POINT_STRIDE = 4
_SEARCH_SIGMA_M = 0.1
# Two search optima closer than this are the same place hypothesis [m, deg].
_DISTINCT_M = 1.0
_DISTINCT_DEG = 30.0


class PlaceSearch:
    """Where could a scan be in an island? A brute-force correlative search of the island's
    line model (as a distance field) over positions within the coverage radius and all
    headings; the score of a pose is the mean of exp(-d^2 / 2 sigma^2) over the scan's points,
    d the distance to the model."""

    def __init__(self, model: LineModel, half_extent_m: float, coverage_m: float) -> None:
        from scipy.ndimage import distance_transform_edt

        self.res = _FIELD_RES_M
        self.half = half_extent_m
        n = math.ceil(2 * half_extent_m / self.res) + 1
        occ = np.ones((n, n), dtype=bool)
        for x1, y1, x2, y2 in model.segments:
            k = max(2, int(math.hypot(x2 - x1, y2 - y1) / (self.res / 2)) + 1)
            xs = np.linspace(x1, x2, k)
            ys = np.linspace(y1, y2, k)
            ix = np.round((xs + half_extent_m) / self.res).astype(np.int64)
            iy = np.round((ys + half_extent_m) / self.res).astype(np.int64)
            ok = (ix >= 0) & (ix < n) & (iy >= 0) & (iy < n)
            occ[iy[ok], ix[ok]] = False
        self.field = (distance_transform_edt(occ) * self.res).astype(np.float64)
        self.n = n
        ticks = np.arange(-coverage_m, coverage_m + 1e-9, _SEARCH_STEP_M)
        gx, gy = np.meshgrid(ticks, ticks)
        inside = np.hypot(gx, gy) <= coverage_m
        self.offsets = np.stack([gx[inside], gy[inside]], axis=1)
        self.headings = np.radians(np.arange(0.0, 360.0, _SEARCH_STEP_DEG))

    def search(self, points: FloatArray) -> tuple[FloatArray, float, float]:
        """(best pose (3,), its score, best score of a distinct hypothesis) for robot-frame
        points; scores are in [0, 1]."""
        pts = points[::_SEARCH_POINT_STRIDE]
        best = (np.zeros(3), -1.0)
        cands: list[tuple[float, float, float, float]] = []
        for th in self.headings:
            c, s_ = math.cos(th), math.sin(th)
            rot = np.stack([c * pts[:, 0] - s_ * pts[:, 1], s_ * pts[:, 0] + c * pts[:, 1]], 1)
            world = rot[None, :, :] + self.offsets[:, None, :]
            ij = np.round((world + self.half) / self.res).astype(np.int64)
            ok = (ij >= 0).all(axis=2) & (ij < self.n).all(axis=2)
            d = np.full(ok.shape, 10.0 * _SEARCH_SIGMA_M)
            d[ok] = self.field[ij[..., 1][ok], ij[..., 0][ok]]
            score = np.mean(np.exp(-0.5 * (d / _SEARCH_SIGMA_M) ** 2), axis=1)
            k = int(np.argmax(score))
            cands.append((float(score[k]), float(self.offsets[k, 0]), float(self.offsets[k, 1]),
                          float(th)))
            if score[k] > best[1]:
                best = (np.array([self.offsets[k, 0], self.offsets[k, 1], th]), float(score[k]))
        bp = best[0]
        second = 0.0
        for sc, x, y, th in cands:
            far = math.hypot(x - bp[0], y - bp[1]) > _DISTINCT_M
            turned = abs(math.degrees(wrap_angles(th - bp[2]))) > _DISTINCT_DEG
            if far or turned:
                second = max(second, sc)
        bp[2] = float(wrap_angles(bp[2]))
        return bp, best[1], second

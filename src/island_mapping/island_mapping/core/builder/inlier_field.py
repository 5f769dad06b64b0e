"""Which points lie within a distance of a line model's walls: exactly the answer of
`point_segment_distance(points, segments).min(axis=1) <= inlier_m`, fast for many points.

The recognizer scores thousands of guesses (each a few hundred points) against one model; a
laser island's model has a hundred or more walls, so the direct test costs points x walls per
guess. `InlierField` computes the distance to the model once at the nodes of a grid of side
`cell_m` around it; a point's distance differs from that of its nearest node by at most the
distance between them (distance to a set is 1-Lipschitz), half a cell diagonal. Points whose
node decides the test with that slack to spare are answered from the grid, the few in the
band around inlier_m by the direct test, and points outside the grid (farther than inlier_m
from every wall's endpoints' bounding box, so from every wall) are outliers.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import point_segment_distance
from island_msgs_py.types import FloatArray

BoolArray = npt.NDArray[np.bool_]

CELL_M = 0.05
"""Grid side [m]: the band answered directly is +-0.035 m around inlier_m."""
MAX_NODES = 1_000_000
"""A model whose grid would be larger is answered directly (at most 4 MB per grid) [-]."""
_NODES_PER_CHUNK = 4096
"""Grid nodes per distance evaluation (bounds the (nodes x walls) temporaries) [-]."""
_TOLERANCE_M = 1e-4
"""Rounding allowance of the grid's decision (the grid is stored in float32) [m]."""


class InlierField:
    """The inlier test of one model (module docstring)."""

    def __init__(self, segments: FloatArray, inlier_m: float, cell_m: float = CELL_M) -> None:
        self.segments = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
        self.inlier_m = float(inlier_m)
        self._cell = float(cell_m)
        self._slack = 0.5 * math.sqrt(2.0) * self._cell + _TOLERANCE_M
        self._grid: npt.NDArray[np.float32] | None = None
        self._lo = np.zeros(2)
        if self.segments.shape[0] == 0:
            return
        ends = self.segments.reshape(-1, 2)
        margin = self.inlier_m + 2.0 * self._cell
        self._lo = ends.min(axis=0) - margin
        shape = np.ceil((ends.max(axis=0) + margin - self._lo) / self._cell).astype(int) + 1
        if int(shape[0]) * int(shape[1]) > MAX_NODES:
            return
        xs = self._lo[0] + self._cell * np.arange(shape[0])
        ys = self._lo[1] + self._cell * np.arange(shape[1])
        gx, gy = np.meshgrid(xs, ys)  # (ny, nx)
        nodes = np.stack([gx.ravel(), gy.ravel()], axis=1)
        dist = np.empty(nodes.shape[0])
        for k in range(0, nodes.shape[0], _NODES_PER_CHUNK):
            part = nodes[k:k + _NODES_PER_CHUNK]
            dist[k:k + _NODES_PER_CHUNK] = point_segment_distance(part, self.segments).min(axis=1)
        self._grid = dist.reshape(gx.shape).astype(np.float32)

    def within(self, points: FloatArray) -> BoolArray:
        """(N,) whether each of (N, 2) points [m] lies within inlier_m of a wall."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if self.segments.shape[0] == 0:
            return np.zeros(pts.shape[0], dtype=bool)
        if self._grid is None:
            return np.asarray(self._direct(pts))
        ny, nx = self._grid.shape
        idx = np.rint((pts - self._lo) / self._cell)
        inside = (idx[:, 0] >= 0) & (idx[:, 0] < nx) & (idx[:, 1] >= 0) & (idx[:, 1] < ny)
        out = np.zeros(pts.shape[0], dtype=bool)
        ix, iy = idx[inside, 0].astype(int), idx[inside, 1].astype(int)
        dn = self._grid[iy, ix]
        sure_in = dn + self._slack <= self.inlier_m
        unsure = ~sure_in & (dn - self._slack <= self.inlier_m)
        rows = np.flatnonzero(inside)
        out[rows[sure_in]] = True
        if np.any(unsure):
            out[rows[unsure]] = self._direct(pts[rows[unsure]])
        return out

    def _direct(self, pts: FloatArray) -> BoolArray:
        return np.asarray(point_segment_distance(pts, self.segments).min(axis=1) <= self.inlier_m)

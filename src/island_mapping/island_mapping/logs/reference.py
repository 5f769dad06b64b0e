"""Reference trajectories (e.g. a SLAM system's corrected poses) and how islands agree with them
(pure: numpy only).

`read_reference(path)`: a text file of poses, one a line: `t x y theta` [s, m, m, rad], or the
TUM format `t x y z qx qy qz qw` (the yaw of the quaternion is kept); `#` comments skipped.

`inside_islands(...)`: for every two scans localized in the same island, the relative pose the
island gives them against the reference's (error e = truth^-1 (+) estimate, as for relations):
without relations, this is how well island-local poses agree with the reference.

`places(...)`: island origins placed by the reference at their anchor scans, joined into places
when closer than `PLACE_RADIUS_M`: how many islands store one place.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import relative_poses
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from island_mapping.core.relations import ErrorStats, Localized, relative_pose_errors
from island_mapping.logs.errors import LogFormatError

FloatArray = npt.NDArray[np.float64]

PLACE_RADIUS_M = 1.5
"""Island origins closer than this (by the reference) store the same place [m]."""
MAX_PAIRS_PER_ISLAND = 2000
"""Scan pairs scored per island at most (evenly chosen; a long stay gives thousands) [-]."""


@dataclass(frozen=True, eq=False)
class Reference:
    """A reference trajectory: times_s (N,) [s] (the log's clock or another: see
    `logs.report`), poses (N, 3) [m, m, rad], and where it came from."""

    times_s: FloatArray
    poses: FloatArray
    name: str


def parse_reference(lines: list[str], source: str) -> Reference:
    """`t x y theta` or TUM `t x y z qx qy qz qw` lines (see the module docstring)."""
    rows: list[tuple[float, float, float, float]] = []
    for lineno, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = text.replace(",", " ").split()
        if len(parts) not in (4, 8):
            raise LogFormatError(f"{source}:{lineno}: expected `t x y theta` or TUM `t x y z qx "
                                 f"qy qz qw`, got {len(parts)} fields")
        try:
            v = [float(p) for p in parts]
        except ValueError as exc:
            raise LogFormatError(f"{source}:{lineno}: not a number ({exc})") from None
        if not all(math.isfinite(x) for x in v):
            raise LogFormatError(f"{source}:{lineno}: NaN or infinite value")
        if len(v) == 8:
            qx, qy, qz, qw = v[4:]
            yaw = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
            rows.append((v[0], v[1], v[2], yaw))
        else:
            rows.append((v[0], v[1], v[2], v[3]))
    if not rows:
        raise LogFormatError(f"{source}: no poses")
    arr = np.asarray(rows, dtype=np.float64)
    return Reference(arr[:, 0], arr[:, 1:], source)


def read_reference(path: str | os.PathLike[str]) -> Reference:
    """Read a reference trajectory file (see `parse_reference`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return parse_reference(f.read().splitlines(), str(path))
    except (OSError, UnicodeDecodeError) as exc:
        raise LogFormatError(f"{path}: cannot read reference trajectory ({exc})") from None


def at_times(ref: Reference, times_s: npt.ArrayLike, offset_s: float,
             tolerance_s: float) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Reference poses (N, 3) at log times (reference time = log time + offset_s), the
    nearest within tolerance_s, and (N,) whether one was."""
    t = np.asarray(times_s, dtype=np.float64).reshape(-1) + offset_s
    order = np.argsort(ref.times_s, kind="stable")
    srt = ref.times_s[order]
    hi = np.clip(np.searchsorted(srt, t), 0, srt.size - 1)
    lo = np.clip(hi - 1, 0, srt.size - 1)
    pick = np.where(np.abs(srt[lo] - t) <= np.abs(srt[hi] - t), lo, hi)
    ok = np.abs(srt[pick] - t) <= tolerance_s
    return ref.poses[order[pick]], ok


def inside_islands(run: Localized, ref_poses: FloatArray, has_ref: npt.NDArray[np.bool_]
                   ) -> tuple[ErrorStats, int]:
    """Agreement of island-local poses with the reference: over pairs of scans localized in
    the same island (and with a reference pose), the relative pose error; (stats, islands)."""
    trans: list[FloatArray] = []
    rot: list[FloatArray] = []
    islands = 0
    for k in np.unique(run.scan_island[run.scan_island >= 0]):
        idx = np.flatnonzero((run.scan_island == k) & has_ref)
        if idx.size < 2:
            continue
        islands += 1
        a, b = np.triu_indices(idx.size, k=1)
        if a.size > MAX_PAIRS_PER_ISLAND:
            pick = np.linspace(0, a.size - 1, MAX_PAIRS_PER_ISLAND).astype(int)
            a, b = a[pick], b[pick]
        i, j = idx[a], idx[b]
        est = relative_poses(run.scan_pose[i], run.scan_pose[j])
        truth = relative_poses(ref_poses[i], ref_poses[j])
        t, r = relative_pose_errors(est, truth)
        trans.append(t)
        rot.append(r)
    if not trans:
        return ErrorStats.of([], []), 0
    return ErrorStats.of(np.concatenate(trans), np.concatenate(rot)), islands


def places(anchor_poses: FloatArray, radius_m: float = PLACE_RADIUS_M) -> dict[str, Any]:
    """Island origins (K, 3) by the reference joined into places (single linkage within
    radius_m): counts, and the places that hold more than one island (island ids)."""
    k = anchor_poses.shape[0]
    if k == 0:
        return {"islands": 0, "places": 0, "islands_per_place": None, "repeated": []}
    pairs = cKDTree(anchor_poses[:, :2]).query_pairs(radius_m, output_type="ndarray")
    from scipy.sparse import coo_matrix

    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
    n, label = connected_components(adj, directed=False)
    repeated = [sorted(int(i) for i in np.flatnonzero(label == c))
                for c in range(n) if np.sum(label == c) > 1]
    return {"islands": int(k), "places": int(n), "islands_per_place": round(k / n, 3),
            "place_radius_m": radius_m, "repeated": repeated}

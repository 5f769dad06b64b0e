"""Reference trajectories (e.g. a SLAM system's corrected poses) and how islands agree with them
(pure: numpy only).

`read_reference(path)`: a text file of poses, one a line: `t x y theta` [s, m, m, rad], or the
TUM format `t x y z qx qy qz qw` (the yaw of the quaternion is kept); `#` comments skipped.

`inside_islands(...)`: for every two scans localized in the same island, the relative pose the
island gives them against the reference's (error e = truth^-1 (+) estimate, as for relations):
without relations, this is how well island-local poses agree with the reference.

`places(...)`: island origins placed by the reference at their anchor scans, merged into places
as issue 16's yardstick merges places (within `PLACE_RADIUS_M` of a place's first island, in
build order): how many islands store one place, and which islands duplicate a place (each a
missed loop closure). `closure_errors(...)`: how far each loop closure put an island's origin
from where the reference has it (more than `FALSE_MERGE_M`: a false merge).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import compose_poses, relative_poses

from island_mapping.core.relations import ErrorStats, Localized, relative_pose_errors
from island_mapping.logs.errors import LogFormatError

FloatArray = npt.NDArray[np.float64]

PLACE_RADIUS_M = 2.0
"""An island whose origin lies this close (by the reference) to a place's first island stores
that place again (issue 16's world yardstick merges places within 2 m) [m]."""
FALSE_MERGE_M = 3.0
"""A loop closure that puts an island's origin farther than this from where the reference has
it is a false merge (as the world yardstick's `false_merge_m`) [m]."""
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


def places(island_ids: npt.ArrayLike, origins: FloatArray,
           radius_m: float = PLACE_RADIUS_M) -> dict[str, Any]:
    """Islands (ids in build order) with their origins (K, 3) by the reference, merged into
    places: an island joins the place whose first island's origin is nearest, if within
    radius_m [m], else it founds a place. Counts, the places held by several islands (their
    ids), and each island that duplicates a place (a missed loop closure: the place's first
    island and the distance to it [m])."""
    ids = [int(i) for i in np.asarray(island_ids).reshape(-1)]
    xy = np.asarray(origins, dtype=np.float64).reshape(-1, 3)[:, :2]
    if len(ids) != xy.shape[0]:
        raise ValueError(f"places: {len(ids)} island ids for {xy.shape[0]} origins")
    leaders: list[int] = []  # index of each place's first island
    members: list[list[int]] = []
    duplicates: list[dict[str, Any]] = []
    for k in range(len(ids)):
        d = np.hypot(*(xy[leaders] - xy[k]).T) if leaders else np.zeros(0)
        if d.size and float(d.min()) <= radius_m:
            p = int(np.argmin(d))
            members[p].append(ids[k])
            duplicates.append({"island": ids[k], "place_of": ids[leaders[p]],
                               "distance_m": round(float(d[p]), 3)})
        else:
            leaders.append(k)
            members.append([ids[k]])
    n = len(leaders)
    return {"computable": True, "islands": len(ids), "places": n,
            "islands_per_place": None if n == 0 else round(len(ids) / n, 3),
            "place_radius_m": radius_m,
            "places_with_several": [m for m in members if len(m) > 1],
            "duplicates": duplicates}


def no_places(why: str) -> dict[str, Any]:
    """The places entry when they cannot be computed (no reference), saying why."""
    return {"computable": False, "why": why}


def closure_errors(closures: list[tuple[int, int, FloatArray]], ref_poses: FloatArray,
                   has_ref: npt.NDArray[np.bool_], anchor_scan: dict[int, int],
                   false_merge_m: float = FALSE_MERGE_M) -> dict[str, Any]:
    """Loop closures (scan, island id, the scan's pose in the island frame (3,)) against the
    reference: where each puts the island's origin (the scan's reference pose composed with
    the inverse of its island pose) against the island's own origin by the reference (its
    anchor scan's); the errors [m] and the false merges (farther than false_merge_m)."""
    errors: list[dict[str, Any]] = []
    for scan, island, pose in closures:
        a = anchor_scan[island]
        if not (has_ref[scan] and has_ref[a]):
            continue
        # the origin = ref[scan] (+) pose^-1 (the scan is at `pose` in the island frame)
        inv = relative_poses(np.asarray(pose, dtype=np.float64), np.zeros(3))
        origin = compose_poses(ref_poses[scan], inv)[0]
        err = math.hypot(origin[0] - ref_poses[a, 0], origin[1] - ref_poses[a, 1])
        errors.append({"scan": int(scan), "island": int(island), "origin_error_m": round(err, 3)})
    return {"scored": len(errors), "false_merge_m": false_merge_m,
            "false_merges": sum(e["origin_error_m"] > false_merge_m for e in errors),
            "closures": errors}

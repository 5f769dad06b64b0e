"""Relative pose errors on ground-truth relations (Kuemmerle et al. 2009): the GMapping
baseline and islands scored on the same relations (pure: numpy only).

Conventions: poses are rows (x [m], y [m], theta [rad]); a relative pose of b in the frame of a
is a^-1 (+) b; "log time" is a log's time since its start [s]; "relation time" is absolute UNIX
time [s] as in `intel.relations`; relation time = log time + an offset found from the data
(`find_time_offset`: 976052857.338 s on the Intel log, `INTEL_LOG_TO_UNIX_S`) or given.

The GMapping trajectory of `intel.gfs.log` (see ../shared/data/README.md): every `FLASER` line
carries the corrected pose of its scan; every `ODOM` line carries "the corrected pose of the
previous scan plus the raw odometry accumulated since then" (`PoseTrack`, assembled by
island_mapping.logs.carmen.pose_track). A relation time is matched to the nearest log line;
when a scan and an ODOM line are equally near (they often share a timestamp), the scan's
corrected pose wins. Scored on all 2984 relations this gives mean 0.0647 m / 2.13 deg, median
0.0477 m / 1.50 deg (the README's 0.065 / 2.1 and 0.048 / 1.5).

Error of a relation: e = truth^-1 (+) estimate; translation |e_xy| [m], rotation |e_theta| [deg].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import compose_poses, relative_poses

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

# The Intel log's start in UNIX time (shared data README): relation time = log time + this [s].
# Only a fact about that log to check `find_time_offset` against; nothing scores with it.
INTEL_LOG_TO_UNIX_S = 976052857.338
# Relation times sampled when searching the offset (spread over the relations) [-].
OFFSET_SAMPLE = 200
# The earliest relation times whose distances to every log line are candidate offsets [-].
OFFSET_ANCHORS = 3
# A relation time matches a scan when they differ by at most this [s] (scans are ~3.35 s apart,
# relation timestamps sit within 6 ms of a log line).
SCAN_MATCH_TOLERANCE_S = 0.010


class RelationsError(InputError):
    """Inconsistent relation-scoring input; the message names what was wrong."""


def relative_pose_errors(
    estimated: npt.ArrayLike, truth: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Per-row error of estimated relative poses against true ones (Kuemmerle et al. 2009).

    The error is truth^-1 (+) estimated; returns (translation error [m], |rotation error| [deg]).
    """
    err = relative_poses(truth, estimated)
    return np.hypot(err[:, 0], err[:, 1]), np.degrees(np.abs(err[:, 2]))


@dataclass(frozen=True)
class ErrorStats:
    """Summary of relative pose errors over a set of relations."""

    count: int
    mean_trans_err_m: float
    median_trans_err_m: float
    mean_rot_err_deg: float
    median_rot_err_deg: float

    @staticmethod
    def of(trans_m: npt.ArrayLike, rot_deg: npt.ArrayLike) -> ErrorStats:
        """Statistics of per-relation errors; NaN statistics when there are none."""
        t = np.asarray(trans_m, dtype=np.float64).reshape(-1)
        r = np.asarray(rot_deg, dtype=np.float64).reshape(-1)
        if t.size == 0:
            nan = float("nan")
            return ErrorStats(0, nan, nan, nan, nan)
        return ErrorStats(
            int(t.size),
            float(np.mean(t)),
            float(np.median(t)),
            float(np.mean(r)),
            float(np.median(r)),
        )

    def as_dict(self, prefix: str = "") -> dict[str, float | int | None]:
        """JSON-ready dict (NaN becomes None)."""

        def clean(v: float) -> float | None:
            return None if math.isnan(v) else round(v, 6)

        return {
            f"{prefix}count": self.count,
            f"{prefix}mean_trans_err_m": clean(self.mean_trans_err_m),
            f"{prefix}median_trans_err_m": clean(self.median_trans_err_m),
            f"{prefix}mean_rot_err_deg": clean(self.mean_rot_err_deg),
            f"{prefix}median_rot_err_deg": clean(self.median_rot_err_deg),
        }


# --------------------------------------------------------------------------------------------
# Relations, times, the GMapping trajectory
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Relations:
    """Ground-truth relative poses: pose at t2_s in the frame of the pose at t1_s.

    t1_s, t2_s: (N,) absolute UNIX times [s]; rel: (N, 3) (x [m], y [m], yaw [rad]).
    """

    t1_s: FloatArray
    t2_s: FloatArray
    rel: FloatArray

    def __len__(self) -> int:
        return int(self.t1_s.shape[0])


def match_times(
    query_s: npt.ArrayLike, reference_s: npt.ArrayLike, tolerance_s: float = SCAN_MATCH_TOLERANCE_S
) -> IntArray:
    """Index of the nearest reference time for each query time, -1 when farther than tolerance.

    `reference_s` need not be sorted. Among references with equal times (the Intel log stores
    6 significant digits: 10 ms steps after 1000 s) the first in input order is taken.
    """
    q = np.asarray(query_s, dtype=np.float64).reshape(-1)
    ref = np.asarray(reference_s, dtype=np.float64).reshape(-1)
    if ref.size == 0:
        return np.full(q.shape, -1, dtype=np.int64)
    order = np.argsort(ref, kind="stable")
    srt = ref[order]
    hi = np.clip(np.searchsorted(srt, q), 0, srt.size - 1)
    lo = np.clip(hi - 1, 0, srt.size - 1)
    pick = np.where(np.abs(srt[lo] - q) <= np.abs(srt[hi] - q), lo, hi)
    pick = np.searchsorted(srt, srt[pick], side="left")  # first of a block of equal times
    idx = order[pick].astype(np.int64)
    idx[np.abs(ref[idx] - q) > tolerance_s] = -1
    return idx


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """Poses at every FLASER and ODOM line of a GMapping-corrected CARMEN log, in file order.

    times_s: (M,) log time [s] (ODOM lines with time 0 are not odometry: they repeat the scan);
    gmapping: (M, 3) the GMapping pose (corrected for scans, corrected + raw odometry between);
    raw: (M, 3) raw odometry (an arbitrary but fixed frame);
    is_scan: (M,) True on FLASER lines; scan_index: (M,) index of the latest scan at or before
    the line (-1 before the first scan).
    """

    times_s: FloatArray
    gmapping: FloatArray
    raw: FloatArray
    is_scan: BoolArray
    scan_index: IntArray

    @property
    def scan_rows(self) -> IntArray:
        """Row indices of the scans, in scan order."""
        return np.flatnonzero(self.is_scan).astype(np.int64)


@dataclass(frozen=True)
class TimeOffset:
    """Relation time = log time + offset_s; `matched` of `times` relation times lie within the
    tolerance of a log line with it; `source` says whether it was found or given."""

    offset_s: float
    matched: int
    times: int
    source: str

    def as_dict(self) -> dict[str, float | int | str]:
        return {"offset_s": round(self.offset_s, 6), "matched_times": self.matched,
                "relation_times": self.times, "source": self.source}


def _matches(rel_t: FloatArray, lines: FloatArray, offsets: FloatArray,
             tolerance_s: float) -> npt.NDArray[np.int64]:
    """Per candidate offset, how many relation times lie within tolerance of a (sorted) line."""
    q = rel_t[None, :] - offsets[:, None]
    hi = np.clip(np.searchsorted(lines, q), 0, lines.size - 1)
    lo = np.clip(hi - 1, 0, lines.size - 1)
    d = np.minimum(np.abs(lines[hi] - q), np.abs(lines[lo] - q))
    return np.sum(d <= tolerance_s, axis=1).astype(np.int64)


def find_time_offset(relation_times_s: npt.ArrayLike, line_times_s: npt.ArrayLike,
                     tolerance_s: float = SCAN_MATCH_TOLERANCE_S) -> TimeOffset:
    """The offset (relation time - log time) [s] that puts the most relation times on log
    lines: one of the earliest relation times lies on some line, so every `first - line` is a
    candidate, scored on a sample of relation times; then the best is refined on all of them in
    1 ms steps (ties: the middle of the best run). 0 is a candidate too (relations in log time).
    RelationsError when fewer than half the relation times then lie on a line (the relations
    are not of this log)."""
    rel_t = np.unique(np.asarray(relation_times_s, dtype=np.float64).reshape(-1))
    lines = np.sort(np.asarray(line_times_s, dtype=np.float64).reshape(-1))
    if rel_t.size == 0 or lines.size == 0:
        raise RelationsError("time offset: no relation times or no log lines")
    sample = rel_t[np.linspace(0, rel_t.size - 1, min(OFFSET_SAMPLE, rel_t.size)).astype(int)]
    firsts = rel_t[:OFFSET_ANCHORS]  # one of them lies on a line (the first may not be logged)
    cands = np.concatenate([[0.0], *(t - lines for t in firsts)])
    best = np.zeros(cands.size, dtype=np.int64)
    for k in range(0, cands.size, 2000):  # bounded temporaries
        best[k:k + 2000] = _matches(sample, lines, cands[k:k + 2000], tolerance_s)
    c0 = float(cands[int(np.argmax(best))])
    step_s = 0.1 * tolerance_s  # 1 ms for the 10 ms default
    steps: FloatArray = c0 + step_s * np.arange(-10, 11, dtype=np.float64)
    counts = _matches(rel_t, lines, steps, tolerance_s)
    top = np.flatnonzero(counts == counts.max())
    offset = float(steps[int(top[len(top) // 2])])  # the middle of the best offsets
    matched = int(counts.max())
    if matched * 2 < rel_t.size:
        raise RelationsError(
            f"time offset: with the best offset {offset:.3f} s only {matched} of {rel_t.size} "
            f"relation times lie within {tolerance_s * 1e3:g} ms of a log line: the relations "
            "are not of this log (or give --time-offset-s)")
    return TimeOffset(offset, matched, int(rel_t.size), "found from the log")


def in_span(relations: Relations, t_min_s: float, t_max_s: float, offset_s: float,
            tolerance_s: float = SCAN_MATCH_TOLERANCE_S) -> BoolArray:
    """(N,) relations whose two times (minus offset_s) lie within the log's time span."""
    lo, hi = t_min_s - tolerance_s, t_max_s + tolerance_s
    t1, t2 = relations.t1_s - offset_s, relations.t2_s - offset_s
    return (t1 >= lo) & (t1 <= hi) & (t2 >= lo) & (t2 <= hi)


def subset(relations: Relations, keep: BoolArray) -> Relations:
    """The relations where `keep` is True."""
    return Relations(relations.t1_s[keep], relations.t2_s[keep], relations.rel[keep])


def gmapping_poses_at(track: PoseTrack, times_unix_s: npt.ArrayLike,
                      offset_s: float = 0.0) -> FloatArray:
    """The GMapping (reference) pose at relation times (log time + offset_s): the nearest log
    line, a scan winning ties; (N, 3)."""
    t = np.asarray(times_unix_s, dtype=np.float64).reshape(-1) - offset_s
    scan_rows = track.scan_rows
    odom_rows = np.flatnonzero(~track.is_scan)
    i_s = scan_rows[match_times(t, track.times_s[scan_rows], math.inf)]
    if odom_rows.size == 0:
        return track.gmapping[i_s]
    i_o = odom_rows[match_times(t, track.times_s[odom_rows], math.inf)]
    use_scan = np.abs(track.times_s[i_s] - t) <= np.abs(track.times_s[i_o] - t)
    return track.gmapping[np.where(use_scan, i_s, i_o)]


def gmapping_relation_errors(
    track: PoseTrack, relations: Relations, offset_s: float = 0.0
) -> tuple[FloatArray, FloatArray]:
    """Per-relation (translation [m], rotation [deg]) errors of the GMapping trajectory."""
    p1 = gmapping_poses_at(track, relations.t1_s, offset_s)
    p2 = gmapping_poses_at(track, relations.t2_s, offset_s)
    return relative_pose_errors(relative_poses(p1, p2), relations.rel)


# --------------------------------------------------------------------------------------------
# Scoring island localization on the relations
# --------------------------------------------------------------------------------------------


class Localized(Protocol):
    """Scans localized in islands: scan_island (S,) the island of each scan (-1: none) and
    scan_pose (S, 3) its pose in that island's frame (NaN when none)."""

    @property
    def scan_island(self) -> IntArray: ...

    @property
    def scan_pose(self) -> FloatArray: ...


@dataclass(frozen=True, eq=False)
class RelationScore:
    """Island localization scored on ground-truth relations.

    covered: (N,) both ends localized in the same island; island: (N,) that island (-1);
    trans_err_m, rot_err_deg: (N,) errors of covered relations (NaN elsewhere);
    islands: statistics over covered relations; gmapping_covered / gmapping_all: the GMapping
    trajectory on the same covered relations and on all relations; ends_at_scans: relations
    whose two times both have a pose source (a scan within tolerance, or a bridge);
    unresolvable: relations left out because both ends fall on the same scan or log line.
    """

    covered: BoolArray
    island: IntArray
    trans_err_m: FloatArray
    rot_err_deg: FloatArray
    islands: ErrorStats
    gmapping_covered: ErrorStats
    gmapping_all: ErrorStats
    ends_at_scans: int
    unresolvable: int = 0


def island_poses_at(
    run: Localized,
    scan_times_s: npt.ArrayLike,
    times_unix_s: npt.ArrayLike,
    *,
    track: PoseTrack | None = None,
    bridge_s: float = 0.0,
    tolerance_s: float = SCAN_MATCH_TOLERANCE_S,
    offset_s: float = 0.0,
) -> tuple[IntArray, FloatArray, BoolArray, IntArray]:
    """(island id (N,), island-frame pose (N, 3), has-a-pose-source (N,), source (N,)) at
    relation times (log time + offset_s); source is the scan index, or S + the track row of
    a bridged log line, or -1.

    A time within `tolerance_s` of a scan takes that scan's fix. With a `track` and
    `bridge_s` > 0, a time that matches a log line (within tolerance) but no scan takes the fix
    of the nearer of the scans before and after it (at most `bridge_s` away) composed with the
    raw odometry between that scan and the time.
    """
    t_log = np.asarray(times_unix_s, dtype=np.float64).reshape(-1) - offset_s
    st = np.asarray(scan_times_s, dtype=np.float64).reshape(-1)
    j = match_times(t_log, st, tolerance_s)
    has = j >= 0
    isl = np.where(has, run.scan_island[np.maximum(j, 0)], -1).astype(np.int64)
    pose = np.where(has[:, None], run.scan_pose[np.maximum(j, 0)], np.nan)
    source = j.copy()
    if track is None or bridge_s <= 0:
        return isl, pose, has, source
    rows = track.scan_rows
    if rows.size < st.size:
        raise RelationsError(f"pose track has {rows.size} scans, the run {st.size}")
    line = match_times(t_log, track.times_s, tolerance_s)
    for q in np.flatnonzero(~has & (line >= 0)):
        r = int(line[q])
        best: tuple[float, int] | None = None
        for s in (int(track.scan_index[r]), int(track.scan_index[r]) + 1):
            if 0 <= s < st.size and run.scan_island[s] >= 0:
                dt = abs(st[s] - t_log[q])
                if dt <= bridge_s and (best is None or dt < best[0]):
                    best = (dt, s)
        has[q] = True
        source[q] = st.size + r
        if best is None:
            continue
        s = best[1]
        odo = relative_poses(track.raw[rows[s]], track.raw[r])
        isl[q] = run.scan_island[s]
        pose[q] = compose_poses(run.scan_pose[s], odo)[0]
    return isl, pose, has, source


def score_relations(
    run: Localized,
    scan_times_s: npt.ArrayLike,
    relations: Relations,
    track: PoseTrack | None = None,
    *,
    bridge_s: float = 0.0,
    offset_s: float = 0.0,
) -> RelationScore:
    """Relative pose errors of relations whose two ends were localized in the same island
    (relation time = log time + offset_s)."""
    i1, p1, h1, s1 = island_poses_at(run, scan_times_s, relations.t1_s, track=track,
                                     bridge_s=bridge_s, offset_s=offset_s)
    i2, p2, h2, s2 = island_poses_at(run, scan_times_s, relations.t2_s, track=track,
                                     bridge_s=bridge_s, offset_s=offset_s)
    # Both ends on the same scan (or log line): the estimate is the identity whatever the
    # localization does, so the pair tests nothing. On the Intel log such pairs are 5-15 ms
    # apart in relation time yet 0.3 m apart in truth (the log keeps 6 significant digits).
    unresolvable = (s1 >= 0) & (s1 == s2)
    covered = (i1 >= 0) & (i1 == i2) & ~unresolvable
    n = len(relations)
    trans = np.full(n, np.nan)
    rot = np.full(n, np.nan)
    if np.any(covered):
        est = relative_poses(p1[covered], p2[covered])
        trans[covered], rot[covered] = relative_pose_errors(est, relations.rel[covered])
    if track is not None:
        gt, gr = gmapping_relation_errors(track, relations, offset_s)
        g_cov, g_all = ErrorStats.of(gt[covered], gr[covered]), ErrorStats.of(gt, gr)
    else:
        g_cov = g_all = ErrorStats.of([], [])
    return RelationScore(
        covered, np.where(covered, i1, -1).astype(np.int64), trans, rot,
        ErrorStats.of(trans[covered], rot[covered]), g_cov, g_all, int(np.sum(h1 & h2)),
        int(np.sum(unresolvable)),
    )

"""Loop closure for the builder's passive mode (`core.builder.passive`): the same search and
gate as the live builder, fed from a recording.

The live builder asks its `Recognizer` whether a star's echoes show a known island before it
accepts a new one, and keeps the recognition only when its hooks' gate agrees
(`hooks.gate_refusal`; exploration's gate, `core.explore.loop_closure_gate`: at the place,
within the full covariance propagated since the island's origin was last known, an exit facing
the arrival). The passive mode asks the same before each attempt. What a recording replaces:

- the star's echoes: the scans of the window around the anchor scan, placed by odometry in
  the anchor's frame, the echoes within `revisit.max_range_m` of their scan, thinned to
  `revisit.star_max_points` (`recognition_points`);
- the path the robot came along (for the arrival direction): the odometric positions of the
  scans before, in the robot's frame at the anchor, end first (`approach_polyline`).

`PassiveRevisit` records each recognition kept; `closure_counts` sums them up with the
refusals (`Diagnostics.revisit_refusals`, by reason, as the live builder counts them).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from island_msgs_py.geometry import from_frame, relative_poses
from island_msgs_py.types import FloatArray

from island_mapping.core.builder.config import RevisitConfig
from island_mapping.core.builder.diagnostics import Diagnostics
from island_mapping.core.builder.events import EventKind
from island_mapping.core.lines import thin_evenly


@dataclass(frozen=True, eq=False)
class PassiveRevisit:
    """A known island recognised at a scan and kept by the gate (a loop closed)."""

    scan: int
    island_id: int
    pose: FloatArray  # (3,) the scan in the island's frame [m, m, rad]
    mahalanobis2: float | None  # the gate's squared Mahalanobis distance [-]
    residual_m: float


def recognition_points(window: Sequence[tuple[FloatArray, FloatArray]], anchor_odom: FloatArray,
                       rc: RevisitConfig) -> FloatArray:
    """The star's echoes of a recording: per window scan (robot-frame points (N, 2) [m], its
    odometric pose (3,)), the points within rc.max_range_m of the robot, placed by odometry in
    the frame of the anchor scan's odometric pose, thinned evenly to rc.star_max_points."""
    clouds = []
    for pts, odom in window:
        near = pts[np.hypot(pts[:, 0], pts[:, 1]) <= rc.max_range_m]
        clouds.append(from_frame(near, relative_poses(anchor_odom, odom)[0]))
    if not clouds:
        return np.zeros((0, 2))
    return thin_evenly(np.concatenate(clouds), rc.star_max_points)


def approach_polyline(odoms: Sequence[FloatArray], back_m: float) -> FloatArray:
    """The path up to the last of `odoms` (odometric poses (3,), oldest first), walked back
    from it for back_m [m], as a polyline (K, 2) in the robot's frame there, the end first
    (what `hooks.approach_path` gives from a strategy)."""
    if not odoms:
        return np.zeros((1, 2))
    end = odoms[-1]
    pts = [np.zeros(2)]
    walked = 0.0
    for odom in reversed(odoms[:-1]):
        p = relative_poses(end, odom)[0][:2]
        walked += float(np.hypot(*(p - pts[-1])))
        pts.append(p)
        if walked >= back_m:
            break
    return np.asarray(pts, dtype=np.float64)


def closure_counts(diagnostics: Diagnostics, tried: int, revisits: Sequence[PassiveRevisit],
                   reentries: tuple[int, int] = (0, 0)) -> dict[str, Any]:
    """Loop closure over a run: recognitions tried (before an attempt), kept by the gate,
    every refusal by reason (hypotheses and whole recognitions, counted as the live builder
    counts them), and the passive tracker's re-entries into islands near by odometry (all,
    and those after a loop's length of path since the island was last localized in)."""
    d2 = [r.mahalanobis2 for r in revisits if r.mahalanobis2 is not None]
    return {
        "tried": tried,
        "accepted": diagnostics.counts[EventKind.ISLAND_REVISITED],
        "refused": dict(sorted(diagnostics.revisit_refusals.items())),
        "largest_mahalanobis2": None if not d2 else round(max(d2), 3),
        "revisited_islands": sorted({r.island_id for r in revisits}),
        "tracker_reentries": reentries[0],
        "tracker_reentries_after_loop": reentries[1],
    }


"""Why closures are missed: at each star near a known island, that island's estimates.

  python bench/diagnose/missed_closures.py paper_fig4 2 6000

Wraps `Recognizer.recognize` from outside (its answer is returned unchanged). At each star
whose true position lies within NEAR_M of a known island's true origin, one JSON line: the
island truly there, the one recognized (or None), the look-alike hypotheses, the refusals
this recognition counted (reason: count, any candidate), and each of the recognizer's
estimates of that island's origin as (error [m], error [deg], claimed sigma [m], claimed
sigma [deg]), the error against the origin put in the odometry frame by the truth at that
moment.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from typing import Any

from island_mapping.core.builder import IslandBuilder
from island_mapping.core.builder.recognition import Recognizer
from island_msgs_py.types import Island, Pose2D, wrap_angle
from run import explore, parse

NEAR_M = 2.5  # a star this near a known island's true origin is at its place [m]


def _true_island(islands: list[Island], truth: Pose2D) -> Island | None:
    near = [(math.hypot(i.origin_truth.x - truth.x, i.origin_truth.y - truth.y), i.id, i)
            for i in islands if i.origin_truth is not None]
    near = [n for n in near if n[0] < NEAR_M]
    return min(near)[2] if near else None


def main() -> None:
    a = parse(__doc__)
    now: dict[str, Any] = {}
    ground_truth, recognize = IslandBuilder.on_ground_truth, Recognizer.recognize

    def ground_truth_(self: IslandBuilder, pose: Pose2D) -> None:
        now["truth"], now["builder"] = pose, self
        ground_truth(self, pose)

    def recognize_(self: Recognizer, points: Any, at: Pose2D, snap: Any, islands: Any,
                   star: bool = False) -> Any:
        before = Counter(self.diagnostics.revisit_refusals)
        out = recognize(self, points, at, snap, islands, star)
        refused = dict(Counter(self.diagnostics.revisit_refusals) - before)
        truth, builder = now["truth"], now["builder"]
        island = _true_island(list(islands), truth) if star else None
        if island is None or island.origin_truth is None:
            return out
        odom = builder._odom  # noqa: SLF001 - the odometric pose now, for the truth's frame
        want = odom.compose(truth.inverse().compose(island.origin_truth))
        ests = [(round(math.hypot(e.x - want.x, e.y - want.y), 2),
                 round(math.degrees(wrap_angle(e.theta - want.theta)), 1), round(sm, 2),
                 round(math.degrees(sth), 1)) for e, sm, sth in self.estimates(island.id, snap)]
        print(json.dumps({"t": round(builder._t, 1), "true": island.id,  # noqa: SLF001
                          "recognized": None if out is None else out.island_id,
                          "look_alikes": [h.island_id for h in self.hypotheses],
                          "refused": refused,
                          "last": snap.last_island_id, "estimates": ests}), flush=True)
        return out

    IslandBuilder.on_ground_truth = ground_truth_  # type: ignore[method-assign]
    Recognizer.recognize = recognize_  # type: ignore[method-assign]
    run = explore(a)
    print(json.dumps({"islands": len(run.graph.islands())}))


if __name__ == "__main__":
    main()

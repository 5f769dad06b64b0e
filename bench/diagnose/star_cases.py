"""Every island search of a star, recorded with the truth, and replayed offline.

  python bench/diagnose/star_cases.py record paper_fig4 3 7200 cases.jsonl
  python bench/diagnose/star_cases.py replay cases.jsonl [more.jsonl ...]

`record` wraps `Recognizer._search` from outside (its answer is returned unchanged) while a
star's points are recognised, and writes one JSON line per search: the island's model, the
points, the odometric estimate and the window searched, and the robot's true pose in that
island's true frame (the truth's odometry relation at that moment puts the island's true
origin in the odometry frame). `replay` searches each case again with the code as it is now
and counts, against the truth: found right (within RIGHT_M and RIGHT_DEG of the true pose),
found wrong (a fit elsewhere: a false merge if accepted), not found while the robot stood
within THERE_M of the island's origin (a missed closure's search), and not found elsewhere.
One recording replays against any version of the search: the same points, side by side.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from island_mapping.core.builder import BuilderConfig, IslandBuilder
from island_mapping.core.builder.recognition import Recognizer, _Window
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D, wrap_angle

RIGHT_M, RIGHT_DEG = 0.5, 10.0  # a fit this near the true pose is right [m, deg]
THERE_M = 2.5  # the robot this near an island's true origin is at its place [m]


def _pose(p: Pose2D) -> list[float]:
    return [round(p.x, 4), round(p.y, 4), round(p.theta, 5)]


def record(world: str, seed: int, sim_s: float, out: Path) -> None:
    from run import explore

    now: dict[str, Any] = {"star": False}
    ground_truth, recognize, search = (IslandBuilder.on_ground_truth, Recognizer.recognize,
                                       Recognizer._search)  # noqa: SLF001
    part = out.with_name(out.name + ".part")  # renamed onto `out` once the run is complete
    f = part.open("w")

    def ground_truth_(self: IslandBuilder, pose: Pose2D) -> None:
        now["truth"], now["builder"] = pose, self
        ground_truth(self, pose)

    def recognize_(self: Recognizer, points: Any, at: Pose2D, snap: Any, islands: Any,
                   star: bool = False) -> Any:
        now["star"], now["at"] = star, at
        try:
            return recognize(self, points, at, snap, islands, star)
        finally:
            now["star"] = False

    def search_(self: Recognizer, island: Island, pts: Any, est: Pose2D, win: _Window,
                count_refusals: bool = True) -> Any:
        out_ = search(self, island, pts, est, win, count_refusals)
        if now["star"] and island.origin_truth is not None:
            truth, odom = now["truth"], now["builder"]._odom  # noqa: SLF001
            origin = odom.compose(truth.inverse().compose(island.origin_truth))
            f.write(json.dumps({
                "t": round(now["builder"]._t, 1), "island": island.id,  # noqa: SLF001
                "primary": count_refusals,
                "segments": np.round(island.model.segments, 4).tolist(),
                "points": np.round(pts, 4).tolist(), "est": _pose(est),
                "window": [win.radius_m, win.max_dth_rad, win.step_m, win.max_residual_m],
                "truth": _pose(now["at"].relative_to(origin)),
                "found": None if out_ is None else _pose(out_.pose)}) + "\n")
        return out_

    IslandBuilder.on_ground_truth = ground_truth_  # type: ignore[method-assign]
    Recognizer.recognize = recognize_  # type: ignore[method-assign]
    Recognizer._search = search_  # type: ignore[method-assign]  # noqa: SLF001
    try:
        explore(argparse.Namespace(world=world, seed=seed, sim_seconds=sim_s))
    finally:
        f.close()
    os.replace(part, out)


def _verdict(found: Pose2D | None, truth: Pose2D) -> str:
    there = math.hypot(truth.x, truth.y) <= THERE_M
    if found is None:
        return "missed there" if there else "none elsewhere"
    right = (math.hypot(found.x - truth.x, found.y - truth.y) <= RIGHT_M
             and abs(math.degrees(wrap_angle(found.theta - truth.theta))) <= RIGHT_DEG)
    return "right" if right else "wrong"


def replay(paths: list[Path]) -> None:
    rec = Recognizer(BuilderConfig())
    then, now = Counter[str](), Counter[str]()
    changed = Counter[str]()
    for path in paths:
        for line in path.read_text().splitlines():
            c = json.loads(line)
            if not c["primary"]:
                continue
            model = LineModel(np.array(c["segments"]).reshape(-1, 4))
            island = Island(c["island"], model, ModelType.LINE, 0.0, 0.0)
            win = _Window(*c["window"])
            truth = Pose2D(*c["truth"])
            got = rec._search(island, np.array(c["points"]).reshape(-1, 2),  # noqa: SLF001
                              Pose2D(*c["est"]), win, count_refusals=False)
            a = _verdict(None if c["found"] is None else Pose2D(*c["found"]), truth)
            b = _verdict(None if got is None else got.pose, truth)
            then[a] += 1
            now[b] += 1
            if a != b:
                changed[f"{a} -> {b}"] += 1
    print("recorded:", dict(then))
    print("now:     ", dict(now))
    print("changed: ", dict(changed))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("world")
    r.add_argument("seed", type=int)
    r.add_argument("sim_seconds", type=float)
    r.add_argument("out", type=Path)
    q = sub.add_parser("replay")
    q.add_argument("cases", nargs="+", type=Path)
    a = p.parse_args()
    if a.cmd == "record":
        record(a.world, a.seed, a.sim_seconds, a.out)
    else:
        replay(a.cases)


if __name__ == "__main__":
    sys.exit(main())

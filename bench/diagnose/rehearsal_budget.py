"""Where a rehearsal's simulated time goes, and how rehearsals end.

  python bench/diagnose/rehearsal_budget.py paper_fig4 1 7200

Wraps the motions `core.explore.rehearse` calls (from outside: nothing they decide changes)
and sums the simulated seconds of each (go_to the hypothesis' origin, localize_and_dock,
execute_strategy of a trial edge or its reverse, look_scans), then prints each rehearsal's
island, outcome, edges driven, length, and against the truth how far the hypothesis put the
robot from where it stood (under ~1 m: the hypothesis was right, a failed rehearsal a missed
loop closure) and, when confirmed, how far the robot stands from the true origin of the
neighbour it docked at.
"""

from __future__ import annotations

import collections
import math
from collections.abc import Callable, Generator
from typing import Any

import island_mapping.evaluation.explore_exits as harness
from island_mapping.core.explore import rehearse as rh
from run import explore, parse


def main() -> None:
    a = parse(__doc__)
    spent: collections.Counter[str] = collections.Counter()
    calls: collections.Counter[str] = collections.Counter()
    episodes: list[str] = []

    def timed(name: str, f: Callable[..., Generator[Any, None, Any]]
              ) -> Callable[..., Generator[Any, None, Any]]:
        def g(d: Any, *args: Any, **kw: Any) -> Generator[Any, None, Any]:
            t0 = d.sense.t_s
            try:
                return (yield from f(d, *args, **kw))
            finally:
                spent[name] += d.sense.t_s - t0
                calls[name] += 1
        return g

    for name in ("go_to", "localize_and_dock", "execute_strategy", "look_scans"):
        setattr(rh, name, timed(name, getattr(rh, name)))
    looks: list[str] = []
    found = rh._found  # noqa: SLF001

    def found_(d: Any, island: Any, fix: Any, cfg: Any) -> Generator[Any, None, bool]:
        ok = yield from found(d, island, fix, cfg)
        at = ("-" if fix.origin_odom is None else
              f"{math.dist(d.sense.odom.as_array()[:2], fix.origin_odom.as_array()[:2]):.2f} m")
        looks.append(f"{island.id}:{'found' if ok else 'not'}"
                     f"(trusted {fix.trusted}, {at} from its origin)")
        return ok

    rh._found = found_  # type: ignore[assignment]  # noqa: SLF001
    rehearse, robots = rh.rehearse, []
    sim_robot = harness.SimRobot

    def robot_(*args: Any, **kw: Any) -> Any:
        robots.append(sim_robot(*args, **kw))
        return robots[-1]

    harness.SimRobot = robot_  # type: ignore[misc,assignment]

    def rehearse_(d: Any, graph: Any, hyp: Any, *args: Any, **kw: Any
                  ) -> Generator[Any, None, Any]:
        t0, before = d.sense.t_s, calls["execute_strategy"]
        truth = graph.get_island(hyp.island_id).origin_truth
        off = (float("nan") if truth is None else math.dist(
            truth.compose(hyp.pose).as_array()[:2], robots[-1].true_pose.as_array()[:2]))
        looks.clear()
        got = yield from rehearse(d, graph, hyp, *args, **kw)
        end = "; looks " + ", ".join(looks)
        if got.confirmed and got.trial is not None:
            there = graph.get_island(got.trial.neighbour).origin_truth
            if there is not None:
                end += (f", docked at island {got.trial.neighbour} "
                       f"{math.dist(there.as_array()[:2], robots[-1].true_pose.as_array()[:2]):.2f}"
                       " m from its true origin")
        episodes.append(f"island {hyp.island_id:3d}  {'confirmed' if got.confirmed else 'not'}"
                        f"  {calls['execute_strategy'] - before} edge drives"
                        f"  {d.sense.t_s - t0:6.1f} s  hypothesis {off:5.2f} m off the truth{end}")
        return got

    rh.rehearse = rehearse_  # type: ignore[assignment]
    import island_mapping.core.explore.trips as trips
    trips.rehearse = rehearse_  # type: ignore[assignment]
    explore(a)
    for name, s in spent.most_common():
        print(f"{s:8.0f} s  {calls[name]:5d} calls  {s / calls[name]:6.1f} s each  {name}")
    print("\n".join(episodes))


if __name__ == "__main__":
    main()

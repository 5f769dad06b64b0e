"""Every arrival of a run against the truth: which path made it, how well the look fit.

  python bench/diagnose/arrivals.py paper_fig4 4 7200 [--out ARRIVALS.jsonl]

Wraps `localize_and_dock` where the explorer's modules call it (from outside: nothing they
decide changes) to know which path asked for the arrival (a route's edge or a way back:
mission; a way back looked for again: relocalize; a trip's end: trips; a rehearsal) with its
estimate and the robot's turn since its last trusted fix, then prints one line per arrival:
island, time, trusted or not, its error against the true pose in the island's frame (false
when trusted and > 0.5 m or > 10 deg off), the fit's matched share of the look's echoes, its
residual and constraint, and how far the estimate it started from was off the truth. With
--out, the same as JSON lines.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
from collections.abc import Generator
from pathlib import Path
from typing import Any

import island_mapping.evaluation.explore_exits as harness
from island_msgs_py.types import wrap_angle
from run import explore

_PATHS = ("mission", "relocalize", "trips", "rehearse")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("world")
    p.add_argument("seed", type=int)
    p.add_argument("sim_seconds", type=float)
    p.add_argument("--out", type=Path)
    a = p.parse_args()
    asked: list[tuple[str, Any, float]] = []  # (path, estimate, turn since the last fix)

    def tagged(module: Any, path: str) -> None:
        inner = module.localize_and_dock

        def wrapped(d: Any, island: Any, estimate: Any, *args: Any, **kw: Any
                    ) -> Generator[Any, None, Any]:
            asked.append((path, estimate, d.spun_rad))
            try:
                return (yield from inner(d, island, estimate, *args, **kw))
            finally:
                asked.pop()

        module.localize_and_dock = wrapped

    for path in _PATHS:
        tagged(importlib.import_module(f"island_mapping.core.explore.{path}"), path)
    rows: list[dict[str, Any]] = []
    judge = harness._Judge.__call__  # noqa: SLF001

    def judged(self: Any, fix: Any) -> None:
        n = len(self.checks)
        judge(self, fix)
        if len(self.checks) == n:
            return
        c = self.checks[-1]
        truth = self.robot.true_pose.relative_to(self.graph.get_island(fix.island_id).origin_truth)
        path, est, spun = asked[-1] if asked else ("?", None, math.nan)
        r = fix.result
        rows.append({
            "island": fix.island_id, "t_s": round(c.t_s, 1), "path": path,
            "trusted": fix.trusted, "false": c.false, "error_m": round(c.error_m, 3),
            "error_deg": round(c.error_deg, 1), "matched": round(r.matched_fraction, 3),
            "residual_m": round(r.residual_m, 4), "constraint": round(r.constraint, 3),
            "spun_deg": round(math.degrees(spun)),
            "estimate_off_m": None if est is None else round(
                math.hypot(est.x - truth.x, est.y - truth.y), 2),
            "estimate_off_deg": None if est is None else round(
                math.degrees(wrap_angle(est.theta - truth.theta)), 1)})

    harness._Judge.__call__ = judged  # type: ignore[method-assign]  # noqa: SLF001
    explore(argparse.Namespace(world=a.world, seed=a.seed, sim_seconds=a.sim_seconds))
    for r in rows:
        print(f"island {r['island']:3d} {r['t_s']:7.1f} s {r['path']:10s} "
              f"{'trusted' if r['trusted'] else 'unsure ':7s} {r['error_m']:5.2f} m "
              f"{r['error_deg']:5.1f} deg  matched {r['matched']:.2f}  residual "
              f"{r['residual_m']:.3f} m  turned {r['spun_deg']:6d} deg  estimate off "
              f"{r['estimate_off_m']} m {r['estimate_off_deg']} deg"
              f"{'  FALSE' if r['false'] else ''}")
    print(f"{len(rows)} arrivals, {sum(r['trusted'] for r in rows)} trusted, "
          f"{sum(r['false'] for r in rows)} false")
    if a.out is not None:
        part = a.out.with_suffix(a.out.suffix + ".part")
        part.write_text("".join(json.dumps(r) + "\n" for r in rows))
        part.replace(a.out)


if __name__ == "__main__":
    main()

"""Route evaluation (the second half of `islands explore`): where its time goes, and what the
process pool and the simulator's near-wall caches buy, measured side by side in one run.

  python bench/bench_route_eval.py [--map DIR] [--routes N] [--workers N] [--profile-pairs K]

The map: DIR written by `islands explore` (graph.json, and summary.json whose builder events give
each island's odometric pose for the global-odometry baseline), or by default an offline
exploration of paper_fig4 (seed 1, --sim-seconds 600).

Prints
- where the time of a sequential evaluation goes (cProfile over its first K pairs, cumulative
  time of the simulator's sonar scans and physics steps, localization, hallway perception);
- per-step pieces on the same poses, old path vs new: the wall distance of a physics step
  (geometry.clearance_m vs WallClearance), one sonar scan (the world's caster vs
  NearbyRayCaster), a physics step with and without the covariance route trips never read;
  each checked to give identical answers;
- evaluate_routes with 1 worker vs N (default: one per CPU) on the same pairs: wall time and
  whether every result is identical, and the CPU seconds each spent (what N idle cores could
  make of the pool). Two workers halve the time only on an idle machine: the 1-minute load is
  printed before and after.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import math
import os
import pstats
import resource
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.explore import explore
from island_mapping.evaluation.navigate import SimSetup
from island_mapping.evaluation.routes import evaluate_routes
from island_msgs_py.geometry import clearance_m
from island_msgs_py.json_io import pose_from_dict
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.types import Pose2D
from island_sim.core.near_walls import WallClearance
from island_sim.core.robot import SimRobot
from island_sim.core.sonar import SonarModel
from island_sim.core.world_loader import load_world

# Functions whose cumulative time says where an evaluation's time goes: (label, file, name).
_PARTS = (
    ("sonar scans (ray casting)", "island_sim/core/sonar.py", "scan"),
    ("physics steps (SimRobot.step)", "island_sim/core/robot.py", "step"),
    ("localization (localize)", "island_mapping/core/localize.py", "localize"),
    ("hallway perception (perceive)", "island_msgs_py/hall_perception.py", "perceive"),
)


def _inputs(args: argparse.Namespace) -> tuple[TopoGraph, dict[int, Pose2D], SimSetup, str]:
    if args.map:
        out = Path(args.map)
        summary = json.loads((out / "summary.json").read_text())
        origins = {int(e["island_id"]): pose_from_dict(e["anchor_odom"])
                   for e in summary["builder_events"]
                   if e.get("kind") == "island_accepted" and e.get("anchor_odom")
                   and "island_id" in e}
        world = load_world(summary["world_spec"], summary.get("resolution_m"))
        return (TopoGraph.load_json(out / "graph.json"), origins, SimSetup(world=world),
                f"{out} ({summary['world']}, seed {summary['seed']})")
    setup = SimSetup(world=load_world("paper_fig4"))
    t0 = time.perf_counter()
    res = explore(setup, args.sim_seconds, rng=np.random.default_rng(1))
    print(f"offline exploration of paper_fig4, seed 1, {args.sim_seconds:.0f} s: "
          f"{time.perf_counter() - t0:.1f} s wall")
    return res.graph(), dict(res.origins_odom), setup, "offline paper_fig4 seed 1"


def _best_of(fn: Callable[[], object], repeats: int = 3) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _walk(graph: TopoGraph, n: int) -> np.ndarray:
    """(n, 3) poses: a random walk of 1 cm steps around the islands' true origins."""
    rng = np.random.default_rng(0)
    starts = [i.origin_truth.as_array() for i in graph.islands() if i.origin_truth is not None]
    per = max(1, n // max(1, len(starts)))
    out = [s + np.cumsum(rng.normal(0.0, [0.01, 0.01, 0.02], (per, 3)), axis=0) for s in starts]
    return np.vstack(out)[:n]


def _pieces(setup: SimSetup, poses: np.ndarray) -> None:
    world, segs = setup.world, setup.world.segments
    walls = WallClearance(segs)
    old = [float(clearance_m(p[None, 0:2], segs)[0]) for p in poses]
    new = [walls.at(float(p[0]), float(p[1])) for p in poses]
    assert old == new, "WallClearance differs from clearance_m"
    t_old = _best_of(lambda: [clearance_m(p[None, 0:2], segs) for p in poses])
    def fresh() -> list[float]:  # gathering included: a new cache for the whole walk
        w = WallClearance(segs)
        return [w.at(float(p[0]), float(p[1])) for p in poses]
    t_new = _best_of(fresh)
    _row("wall distance per physics step", t_old, t_new, len(poses))

    sonar = SonarModel(setup.sonar)
    near = NearbyRayCaster(world, setup.sonar.range_max_m)
    pp = [Pose2D(*p) for p in poses[::5]]  # a scan per sensor period: 5 physics steps
    for k, p in enumerate(pp):
        a = sonar.scan(world, p, np.random.default_rng(k))
        b = sonar.scan(near, p, np.random.default_rng(k))
        assert np.array_equal(a, b), "NearbyRayCaster's scan differs from the world's"
    rng = np.random.default_rng(0)
    t_old = _best_of(lambda: [sonar.scan(world, p, rng) for p in pp])
    t_new = _best_of(lambda: [sonar.scan(near, p, rng) for p in pp])
    _row("sonar scan (80 rays)", t_old, t_new, len(pp))

    start = Pose2D(*poses[0])
    def drive(track: bool) -> tuple[Pose2D, Pose2D]:
        r = SimRobot(world, start, np.random.default_rng(0), track_covariance=track)
        for k in range(len(poses)):
            r.step(0.3, 0.2 * math.sin(k / 40.0), 0.02)
        return r.true_pose, r.odom_pose
    assert drive(True) == drive(False), "the robot moved differently without its covariance"
    t_old, t_new = _best_of(lambda: drive(True)), _best_of(lambda: drive(False))
    _row("physics step, covariance kept vs not", t_old, t_new, len(poses))


def _row(what: str, t_old: float, t_new: float, n: int) -> None:
    print(f"  {what:40s} old {1e6 * t_old / n:8.1f} us  new {1e6 * t_new / n:8.1f} us  "
          f"speed-up {t_old / t_new:5.1f}x  (identical answers)")


def _where_time_goes(graph: TopoGraph, setup: SimSetup, origins: dict[int, Pose2D],
                     pairs: int) -> None:
    prof = cProfile.Profile()
    prof.enable()
    evaluate_routes(graph, setup, pairs, np.random.default_rng(1), origins)
    prof.disable()
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    total = sum(v[2] for v in stats.values())  # every function's own time
    print(f"where the time goes (cProfile, first {pairs} pairs, {total:.1f} s profiled):")
    for label, path, name in _PARTS:
        cum = sum(v[3] for (f, _, fn), v in stats.items() if f.endswith(path) and fn == name)
        print(f"  {label:40s} {cum:7.1f} s  {100 * cum / total:5.1f} %")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--map", default="", help="an `islands explore` output directory")
    ap.add_argument("--sim-seconds", type=float, default=600.0,
                    help="offline exploration time without --map [s]")
    ap.add_argument("--routes", type=int, default=20, help="random island pairs (default 20)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--profile-pairs", type=int, default=3)
    args = ap.parse_args()
    graph, origins, setup, name = _inputs(args)
    print(f"map: {name}, {len(graph)} islands; load {os.getloadavg()[0]:.2f}")
    _where_time_goes(graph, setup, origins, args.profile_pairs)
    print("per-step pieces, old path vs new, on the same poses:")
    _pieces(setup, _walk(graph, 3000))
    t0, c0 = time.perf_counter(), _cpu_s(resource.RUSAGE_SELF)
    seq = evaluate_routes(graph, setup, args.routes, np.random.default_rng(1), origins)
    t_seq, c_seq = time.perf_counter() - t0, _cpu_s(resource.RUSAGE_SELF) - c0
    t0, c0 = time.perf_counter(), _cpu_s(resource.RUSAGE_CHILDREN)
    par = evaluate_routes(graph, setup, args.routes, np.random.default_rng(1), origins,
                          workers=args.workers)
    t_par, c_par = time.perf_counter() - t0, _cpu_s(resource.RUSAGE_CHILDREN) - c0
    sim_s = sum(r.sim_time_s for r in (*seq.islands, *seq.baseline))
    print(f"evaluate_routes, {len(seq.pairs)} pairs ({sim_s:.0f} simulated s), identical "
          f"results: {par == seq}; routes by the map {seq.islands_success_rate:.2f}, by "
          f"odometry {seq.baseline_success_rate:.2f}")
    print(f"  1 worker:  {t_seq:6.1f} s wall, {c_seq:6.1f} s CPU")
    print(f"  {args.workers} workers: {t_par:6.1f} s wall, {c_par:6.1f} s CPU in the workers "
          f"(wall speed-up {t_seq / t_par:.2f}x; on {args.workers} idle cores at best "
          f"{c_seq / max(c_par / args.workers, 1e-9):.2f}x); load {os.getloadavg()[0]:.2f}")


def _cpu_s(who: int) -> float:
    """User + system CPU time [s] of this process or of its finished children."""
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


if __name__ == "__main__":
    main()

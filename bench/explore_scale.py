"""How exploration and route evaluation grow with the world's size, and where the time goes
(issue 16): generated offices of 1x, 2x and 4x paper_fig4's area, one process, side by side.

  python bench/explore_scale.py OUT.jsonl --scales 1 2 4 --sim-seconds 600 --routes 5 \
      --modes offline live [--profile]

Per (mode, scale) one JSON line: simulated s, wall s and real-time factor of exploration,
wall s of route evaluation, the world's size (area, places), wall_s and cpu_s of the whole run
(their difference is time spent waiting), and with --profile `where_s`: the wall time split by
component (cProfile; the executor's share includes its waits; a library or built-in
function's own time goes to the project code that called it, in proportion to the calls' own
time; profiled runs are slower).
`offline` is the deterministic harness (`measure_exploration`); `live` is `islands explore`
with every node on one executor, which is what `bash scripts/demo.sh` runs. Every run has one
seed and one sim-time cap, and the scales run one after another in one process, so their
ratios are measured under one load (reported as the 1-minute load average).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

from island_mapping.cli import main as islands
from island_mapping.evaluation.explore_eval import Policy, measure_exploration
from island_sim.core.places import world_places
from island_sim.core.world_loader import load_world

# Where a file's time goes: the first pattern found in its path names the component.
COMPONENTS = (
    ("island_sim/core/sonar", "simulated sonar (ray casting)"),
    ("island_sim/core/world", "simulated sonar (ray casting)"),
    ("island_sim/core/robot", "simulated robot"),
    ("island_sim/core/hall_follower", "hall follower"),
    ("island_sim/core/strategy_record", "hall follower"),
    ("island_sim/nodes", "ROS nodes (conversions, callbacks)"),
    ("island_mapping/core/builder/recognition", "recognition (loop closure search)"),
    ("island_mapping/core/builder", "island builder (eq. 3, star, R)"),
    ("island_mapping/core/explore", "explorer"),
    ("island_mapping/core/route", "route following"),
    ("island_mapping/core/graph", "graph"),
    ("island_mapping/core", "line models, localization"),
    ("island_mapping/nodes", "ROS nodes (conversions, callbacks)"),
    ("island_mapping/conversions", "ROS nodes (conversions, callbacks)"),
    ("island_msgs_py/raycast", "ray casting (sonar, exits)"),
    ("island_msgs_py/hall_perception", "hall follower"),
    ("island_msgs_py", "shared geometry, messages, checks (island_msgs_py)"),
    ("island_mapping/evaluation", "evaluation (harness, routes, world yardstick)"),
    ("island_sim/core", "world yardstick (places, free space)"),
    ("island_mapping/runner", "ROS executor and runner"),
    ("rclpy", "ROS executor and runner"),
)
LIBRARY = ("site-packages", "/lib/python3", "~", "<")


def _component(filename: str) -> str | None:
    """The component a project file belongs to, None for library and built-in code."""
    for pattern, name in COMPONENTS:
        if pattern in filename:
            return name
    return None if any(m in filename for m in LIBRARY) else "other"


def where_time_goes(stats: pstats.Stats) -> dict[str, float]:
    """Own time [s] per component; library time is charged to its project callers."""
    table: dict[Any, Any] = stats.stats  # type: ignore[attr-defined]
    memo: dict[Any, dict[str, float]] = {}

    def shares(func: Any, depth: int = 0) -> dict[str, float]:
        if func in memo:
            return memo[func]
        own = _component(func[0])
        if own is not None or depth > 12 or func not in table:
            memo[func] = {own or "other": 1.0}
            return memo[func]
        callers = table[func][4]
        weights = {caller: c[2] for caller, c in callers.items()}
        if not sum(weights.values()):
            weights = dict.fromkeys(callers, 1.0)
        total = sum(weights.values()) or 1.0
        out: dict[str, float] = defaultdict(float)
        for caller, weight in weights.items():
            w = weight / total
            for comp, f in shares(caller, depth + 1).items():
                out[comp] += w * f
        memo[func] = dict(out) or {"other": 1.0}
        return memo[func]

    seconds: dict[str, float] = defaultdict(float)
    for func, (_cc, _nc, tt, _ct, _callers) in table.items():
        for comp, f in shares(func).items():
            seconds[comp] += tt * f
    return {k: round(v, 2) for k, v in sorted(seconds.items(), key=lambda kv: -kv[1])}


def _offline(world: str, seed: int, sim_s: float, routes: int) -> dict[str, Any]:
    row = measure_exploration(world, Policy.EXITS, seed, sim_s, routes)
    return {"sim_seconds": row["sim_seconds"], "explore_wall_s": row["explore_wall_s"],
            "route_eval_wall_s": round(row["total_wall_s"] - row["explore_wall_s"], 1),
            "islands": row["islands"], "ended_by_itself": row["ended_by_itself"]}


def _live(world: str, seed: int, sim_s: float, routes: int) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        code = islands(["explore", "--world", world, "--policy", Policy.EXITS.value,
                        "--seed", str(seed), "--sim-seconds", str(sim_s), "--routes",
                        str(routes), "--no-record", "--quiet", "--out", str(out)])
        if code != 0:
            return {"error": f"islands explore exit code {code}"}
        s = json.loads((out / "summary.json").read_text())
    return {"sim_seconds": round(s["sim_seconds"], 1), "explore_wall_s": s["wall_seconds"],
            "route_eval_wall_s": s.get("route_eval_wall_seconds"),
            "islands": s.get("world_evaluation", {}).get("islands"),
            "ended_by_itself": s.get("ended_by_itself")}


def measure(mode: str, scale: float, world_seed: int, seed: int, sim_s: float, routes: int,
            profile: bool) -> dict[str, Any]:
    """One run of `mode` on the generated office of `scale`: its times and, with `profile`,
    where they went (then every time includes the profiler's overhead)."""
    world = f"gen:office:seed={world_seed},scale={scale:g}"
    w = load_world(world, None)
    seg = w.segments
    area = float((seg[:, [0, 2]].max() - seg[:, [0, 2]].min())
                 * (seg[:, [1, 3]].max() - seg[:, [1, 3]].min()))
    places = len(world_places(w, None).places)
    prof = cProfile.Profile()
    t0, c0 = time.monotonic(), time.process_time()
    if profile:
        prof.enable()
    row = (_offline if mode == "offline" else _live)(world, seed, sim_s, routes)
    prof.disable()
    wall, cpu = time.monotonic() - t0, time.process_time() - c0
    if "error" not in row:
        row["real_time_factor"] = round(row["sim_seconds"] / max(row["explore_wall_s"], 1e-9), 2)
    return {"mode": mode, "scale": scale, "world": world, "area_m2": round(area),
            "places": places, "seed": seed, **row, "wall_s": round(wall, 1),
            "cpu_s": round(cpu, 1), "profiled": profile,
            "where_s": where_time_goes(pstats.Stats(prof)) if profile else None}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", type=Path)
    p.add_argument("--scales", nargs="+", type=float, default=[1.0, 2.0, 4.0])
    p.add_argument("--modes", nargs="+", choices=["offline", "live"], default=["offline"])
    p.add_argument("--world-seed", type=int, default=7)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--sim-seconds", type=float, default=600.0)
    p.add_argument("--routes", type=int, default=5)
    p.add_argument("--profile", action="store_true",
                   help="also say where the time goes (cProfile; slows every run)")
    a = p.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=False, cwd=Path(__file__).parent).stdout.strip()
    for mode in a.modes:
        for scale in a.scales:
            row = measure(mode, scale, a.world_seed, a.seed, a.sim_seconds, a.routes,
                          a.profile)
            row["load_avg_1m"] = round(os.getloadavg()[0], 2)
            row["commit"] = commit
            with a.out.open("a") as f:
                f.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()

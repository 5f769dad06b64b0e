"""Issue 16's figures per world, policy and seed, offline (no ROS), one JSON line per run.

  python bench/explore_figures.py OUT.jsonl --worlds paper_fig4 gen:office:seed=3,scale=1 \
      --policies exits hall_following --seeds 1 2 3 --sim-seconds 3600 --routes 10

Runs are sequential (one process); a line is appended as soon as a run ends.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
from pathlib import Path

from island_mapping.evaluation.explore_eval import Policy, measure_exploration


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", type=Path)
    p.add_argument("--worlds", nargs="+", default=["paper_fig4"])
    p.add_argument("--policies", nargs="+", default=[Policy.EXITS.value])
    p.add_argument("--seeds", nargs="+", type=int, default=[1])
    p.add_argument("--sim-seconds", type=float, default=3600.0)
    p.add_argument("--routes", type=int, default=10)
    a = p.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=False, cwd=Path(__file__).parent).stdout.strip()
    for world in a.worlds:
        for policy in a.policies:
            for seed in a.seeds:
                row = measure_exploration(world, Policy(policy), seed, a.sim_seconds, a.routes)
                row["load_avg_1m"] = round(os.getloadavg()[0], 2)
                row["commit"] = commit
                with a.out.open("a") as f:
                    f.write(json.dumps(row) + "\n")
                print(json.dumps({k: row[k] for k in (
                    "world", "policy", "seed", "covered_places", "known_places", "places",
                    "covered_junctions", "junctions", "islands", "islands_per_place",
                    "false_merges", "missed_closures",
                    "map_cycle_rank", "map_place_cycle_rank", "world_cycle_rank",
                    "route_success_rate",
                    "route_length_ratio_mean", "wall_contacts", "false_arrivals",
                    "ended_by_itself", "sim_seconds", "explore_wall_s", "load_avg_1m")}),
                    flush=True)


if __name__ == "__main__":
    main()

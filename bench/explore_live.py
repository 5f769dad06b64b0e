"""Issue 16's figures LIVE (every node on one executor, `islands explore --policy P`), one JSON
line per (world, policy, seed), with the same headline keys as `bench/explore_figures.py`
(the offline harness) so that the two can be laid side by side:

  python bench/explore_live.py OUT.jsonl --worlds paper_fig4 gen:office:seed=7,scale=1 \
      --policies exits --seeds 1 --sim-seconds 1800 --routes 5

Runs are sequential, one live run at a time (the machine's 2 cores); a line is appended as
soon as a run ends. Each run's output directory is kept under OUT.jsonl's directory
(`live_<world>_<policy>_<seed>/`). False arrivals are not measured live (the explorer has no
ground truth): the column is null.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import time
from pathlib import Path

from island_mapping.cli import main as islands
from island_mapping.evaluation.explore_eval import HEADLINE, Policy


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", Path(text).name).strip("_")


def run_one(world: str, policy: str, seed: int, sim_s: float, routes: int, out: Path
            ) -> dict[str, object]:
    """One live run of `islands explore`; its headline figures as a flat dict."""
    t0 = time.monotonic()
    code = islands(["explore", "--world", world, "--policy", policy, "--seed", str(seed),
                    "--sim-seconds", str(sim_s), "--routes", str(routes), "--no-record",
                    "--quiet", "--out", str(out)])
    wall = time.monotonic() - t0
    if code != 0:
        return {"world": world, "policy": policy, "seed": seed, "error": f"exit code {code}"}
    s = json.loads((out / "summary.json").read_text())
    ev = s.get("world_evaluation", {})
    return {"world": world, "policy": policy, "seed": seed,
            **{k: ev.get(k) for k in HEADLINE}, "wall_contacts": s["collisions"],
            "false_arrivals": None, "ended_by_itself": s.get("ended_by_itself"),
            "exits_left": s.get("exits_left"), "sim_seconds": round(s["sim_seconds"], 1),
            "explore_wall_s": s["wall_seconds"], "total_wall_s": round(wall, 1),
            "real_time_factor": s["real_time_factor"],
            "lockstep_timeouts": s["lockstep_timeouts"], "explorer": s.get("explorer")}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", type=Path)
    p.add_argument("--worlds", nargs="+", default=["paper_fig4"])
    p.add_argument("--policies", nargs="+", default=[Policy.EXITS.value],
                   choices=[x.value for x in Policy])
    p.add_argument("--seeds", nargs="+", type=int, default=[1])
    p.add_argument("--sim-seconds", type=float, default=1800.0)
    p.add_argument("--routes", type=int, default=5)
    a = p.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=False, cwd=Path(__file__).parent).stdout.strip()
    for world in a.worlds:
        for policy in a.policies:
            for seed in a.seeds:
                out = a.out.parent / f"live_{_slug(world)}_{policy}_{seed}"
                row = run_one(world, policy, seed, a.sim_seconds, a.routes, out)
                row["load_avg_1m"] = round(os.getloadavg()[0], 2)
                row["commit"] = commit
                with a.out.open("a") as f:
                    f.write(json.dumps(row) + "\n")
                print(json.dumps({k: v for k, v in row.items() if k != "explorer"}), flush=True)


if __name__ == "__main__":
    main()

"""Where an exploration's simulated time goes: seconds per explorer state and driver.

  python bench/diagnose/time_budget.py paper_fig4 2 3600

Wraps `Explorer.step` and `IslandBuilder.command` from outside (nothing they decide changes)
and counts each scan (0.1 s) under (explorer state, who drives, builder state).
"""

from __future__ import annotations

import argparse
import collections
from typing import Any

import numpy as np
from island_mapping.core.builder import IslandBuilder
from island_mapping.core.explore import Explorer
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_sim.core.world_loader import load_world

SCAN_S = 0.1  # simulated seconds per scan


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("world")
    p.add_argument("seed", type=int)
    p.add_argument("sim_seconds", type=float)
    a = p.parse_args()
    spent: collections.Counter[tuple[str, str, str]] = collections.Counter()
    last: dict[str, Any] = {}
    command, step = IslandBuilder.command, Explorer.step

    def command_(self: IslandBuilder, t: float) -> Any:
        cmd = command(self, t)
        last["mode"], last["state"] = cmd.mode.name, str(getattr(self, "_state", ""))
        return cmd

    def step_(self: Explorer, sense: Any) -> Any:
        cmd = step(self, sense)
        who = "explorer" if cmd.drive else {"DRIVE": "builder", "FOLLOW": "follower"}.get(
            last["mode"], last["mode"])
        spent[(self.status.to_dict()["state"], who,
               "" if who == "explorer" else last["state"])] += SCAN_S
        return cmd

    IslandBuilder.command, Explorer.step = command_, step_  # type: ignore[method-assign]
    explore_by_exits(SimSetup(world=load_world(a.world, None)), a.sim_seconds,
                     rng=np.random.default_rng(a.seed))
    for key, s in spent.most_common():
        print(f"{s:8.0f} s  {key}")


if __name__ == "__main__":
    main()

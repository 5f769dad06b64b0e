"""Where an exploration's simulated time goes: seconds per explorer state and driver.

  python bench/diagnose/time_budget.py paper_fig4 2 3600

Wraps `Explorer.step` and `IslandBuilder.command` from outside (nothing they decide changes)
and counts each scan (0.1 s) under (explorer state, who drives, builder state), and how
many times each was entered (episodes: the mean length of a star, a rehearsal, a departure).
"""

from __future__ import annotations

import collections
from typing import Any

from island_mapping.core.builder import IslandBuilder
from island_mapping.core.explore import Explorer
from run import explore, parse

SCAN_S = 0.1  # simulated seconds per scan


def main() -> None:
    a = parse(__doc__)
    spent: collections.Counter[tuple[str, str, str]] = collections.Counter()
    entered: collections.Counter[tuple[str, str, str]] = collections.Counter()
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
        key = (str(self.status.to_dict()["state"]), who,
               "" if who == "explorer" else last["state"])
        spent[key] += SCAN_S
        if key != last.get("key"):
            entered[key] += 1
            last["key"] = key
        return cmd

    IslandBuilder.command, Explorer.step = command_, step_  # type: ignore[method-assign]
    explore(a)
    for key, s in spent.most_common():
        print(f"{s:8.0f} s  {entered[key]:5d} times  {s / entered[key]:6.1f} s each  {key}")


if __name__ == "__main__":
    main()

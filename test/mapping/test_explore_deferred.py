"""An exit whose exploration was stopped (the handover stuck in one spot, or run round a room)
and the robot driven back is not given up at once: it is left for later, tried again once no
other exit is left (`ExplorerConfig.retries_per_exit` times), then blocked. Exploration that
gave up both exits of its first islands after one stuck handover each ended by itself with 3
of 138 places of the Willow plan (a false "done")."""

from __future__ import annotations

from island_mapping.core.explore import ExplorerConfig
from island_mapping.core.explore.watch import Deferred


def _plan(deferred: Deferred, blocked: set[tuple[int, int]], open_exits: list[tuple[int, int]]
          ) -> tuple[int, int] | None:
    """What the explorer's choice does: the first open exit not skipped, the skips tried in
    `Deferred.skips` order until one is found."""
    for skip in deferred.skips(blocked):
        left = [e for e in open_exits if e not in skip]
        if left:
            return left[0]
    return None


def test_a_given_up_exit_waits_until_no_other_is_left_then_is_blocked() -> None:
    d = Deferred(ExplorerConfig().retries_per_exit)
    assert d.retries == 1
    blocked: set[tuple[int, int]] = set()
    exits = [(0, 1), (1, 0)]
    assert not d.give_up((0, 1))  # first stop: left for later, not blocked
    assert _plan(d, blocked, exits) == (1, 0)  # another exit first
    assert _plan(d, blocked, exits) == (1, 0)  # and again: it stays left for later
    exits.remove((1, 0))  # that one explored
    assert _plan(d, blocked, exits) == (0, 1)  # nothing else: tried again
    assert d.give_up((0, 1))  # stopped again: now blocked
    blocked.add((0, 1))
    assert _plan(d, blocked, exits) is None  # done
    assert d.deferred == 1


def test_no_retries_blocks_at_once() -> None:
    d = Deferred(0)
    assert d.give_up((2, 0))
    assert _plan(d, {(2, 0)}, [(2, 0)]) is None

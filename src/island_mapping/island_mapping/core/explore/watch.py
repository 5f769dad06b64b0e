"""The explorer's small watches (`core.explore.mission`): a handover stuck in one spot, and
the exits given up for now."""

from __future__ import annotations

import math
from collections.abc import Iterator

from island_mapping.core.route import Sense


class Deferred:
    """Exits whose exploration was stopped (stuck, or round a room) and the robot driven
    back: left for later, tried again once no other exit is left, `retries` times; then
    `give_up` says to block them."""

    def __init__(self, retries: int) -> None:
        self.retries = retries
        self.deferred = 0  # exits left for later, counted each time
        self._keys: set[tuple[int, int]] = set()
        self._tries: dict[tuple[int, int], int] = {}

    def give_up(self, key: tuple[int, int]) -> bool:
        """One more stopped exploration of exit `key`; True: block it now."""
        self._tries[key] = self._tries.get(key, 0) + 1
        if self._tries[key] > self.retries:
            self._keys.discard(key)
            return True
        self._keys.add(key)
        self.deferred += 1
        return False

    def skips(self, blocked: set[tuple[int, int]]) -> Iterator[set[tuple[int, int]]]:
        """The exits to skip in planning: first the blocked and the left for later ones;
        then, resumed because the planner found none, the blocked ones only (the others are
        tried again)."""
        yield blocked | self._keys
        self._keys.clear()
        yield blocked


class StuckWatch:
    """True once the odometric position has stayed within `radius_m` of where it was for
    `window_s` (a star turns in place for less; a robot pushing at a door jamb does not)."""

    def __init__(self, window_s: float, radius_m: float, sense: Sense) -> None:
        self.window_s, self.radius_m = window_s, radius_m
        self._since, self._at = sense.t_s, sense.odom

    def update(self, sense: Sense) -> bool:
        if math.hypot(sense.odom.x - self._at.x, sense.odom.y - self._at.y) > self.radius_m:
            self._since, self._at = sense.t_s, sense.odom
        return sense.t_s - self._since >= self.window_s

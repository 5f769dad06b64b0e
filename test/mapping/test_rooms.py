"""Rooms as places (issue 16): a house of rooms has no hallway to stand islands in.

After room_after_m of path along a room's walls the quick check may attempt there
(`Openings.in_room`); the last island's vicinity ends at a wall of its own model between its
origin and the robot (`Ledger.near_last_island` with sight), since the room behind that wall
is another place however near. Public APIs: `core.builder.opening`, `core.builder.ledger`,
`core.builder.recognition`.
"""

from __future__ import annotations

import numpy as np
from island_mapping.core.builder import BuilderConfig
from island_mapping.core.builder.ledger import Ledger
from island_mapping.core.builder.opening import Openings
from island_mapping.core.builder.opening_config import OpeningConfig
from island_mapping.core.builder.recognition import Recognizer
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

ANGLES = np.radians(np.arange(16) * 22.5)  # a ring of 16 sonars, 0 ahead, CCW


def _walk(ops: Openings, path: list[tuple[float, bool, bool]], start_m: float = 0.0) -> float:
    """Feed (stretch [m], left open, right open) in 0.05 m steps; the path at the end [m]."""
    s = start_m
    for length, left, right in path:
        for _ in range(round(length / 0.05)):
            s += 0.05
            ops.run.update(s, left, right, 0.0, ops.cfg)
    return s


def test_a_long_walk_along_a_rooms_walls_makes_the_room_a_place() -> None:
    cfg = OpeningConfig(enabled=True, room_after_m=6.0)
    room = Openings(cfg)
    # along one wall, the other side open all the way: no hallway
    end = _walk(room, [(3.0, True, False)])
    assert not room.in_hallway(end) and not room.in_room(end)
    end = _walk(room, [(3.5, False, True)], end)
    assert room.in_room(end)
    # a hallway (both sides walls) restarts the count
    end = _walk(room, [(1.0, False, False)], end)
    assert room.in_hallway(end) and not room.in_room(end)
    end = _walk(room, [(5.0, True, False)], end)
    assert not room.in_room(end)
    end = _walk(room, [(1.5, True, False)], end)
    assert room.in_room(end)
    for off in (OpeningConfig(enabled=True, room_after_m=0.0), OpeningConfig(enabled=False)):
        ops = Openings(off)
        assert not ops.in_room(_walk(ops, [(20.0, True, False)]))


# Island 0's model: it stands 1.5 m north of a wall (y = -1.5) with a 0.8 m doorway at
# x = 0.6..1.4; the room behind that wall is another place.
WALL = np.array([[-4.0, -1.5, 0.6, -1.5], [1.4, -1.5, 4.0, -1.5], [-4.0, 2.0, 4.0, 2.0]])


def _ledger_at_island() -> Ledger:
    ledger = Ledger(Recognizer(BuilderConfig()))
    island = Island(0, LineModel(WALL), ModelType.LINE, 1.0, 0.0)
    ledger.add_island(island, Pose2D(0.0, 0.0, 0.0), np.eye(3) * 1e-4, None, 0.0, 0.0)
    return ledger


def test_a_wall_of_the_islands_model_ends_its_vicinity() -> None:
    ledger = _ledger_at_island()
    assert ledger.near_last_island(Pose2D(2.5, 0.5, 0.0), 4.0, sight=True)  # same room
    behind = Pose2D(-1.0, -2.5, 0.0)  # 2.7 m off, through the wall
    assert ledger.near_last_island(behind, 4.0)  # by distance alone
    assert not ledger.near_last_island(behind, 4.0, sight=True)
    # in the doorway, and just past it on the line through the gap: still in sight
    assert ledger.near_last_island(Pose2D(1.0, -1.5, 0.0), 4.0, sight=True)
    assert ledger.near_last_island(Pose2D(1.3, -2.0, 0.0), 4.0, sight=True)
    # beside the wall it follows (within 0.4 m of the robot) the robot is not hidden
    assert ledger.near_last_island(Pose2D(-2.0, -1.2, 0.0), 4.0, sight=True)
    assert not ledger.near_last_island(Pose2D(4.5, 0.0, 0.0), 4.0, sight=True)  # too far

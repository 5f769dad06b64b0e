"""Built-in worlds, generated in code (deterministic).

Each world is the union of free axis-aligned rectangles (corridors, rooms, door gaps) in metres;
everything else is solid, and the walls are the traced outline of the free space (each wall face
is one line segment; a corridor is two parallel walls). Corridors are 2 m wide and doors 1 m, so
a Nomad-size robot (radius 0.25 m) with a 6.5 m sonar can follow the halls.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from island_msgs_py.types import Pose2D

from island_sim.core.importers import rectangles_to_segments
from island_sim.core.world import World, WorldError

Rect = tuple[float, float, float, float]  # (x0, y0, x1, y1) [m]

# Grid the rectangles are rasterized on [m]; every corner below is a multiple of it.
_GRID_M = 0.25


def _paper_fig3_rects() -> list[Rect]:
    """~28 x 28 m like the paper's Fig. 3b: hallways, a + and T intersections, rooms, dead ends."""
    return [
        (1.0, 14.0, 29.0, 16.0),  # H1: main east-west hallway, dead ends at both ends
        (14.0, 1.0, 16.0, 29.0),  # V1: main north-south hallway, + with H1, dead ends
        (6.0, 24.0, 14.0, 26.0),  # H2: T into V1 from the west
        (6.0, 16.0, 8.0, 24.0),  # V2: T up from H1, corner into H2 (a small loop)
        (22.0, 3.0, 24.0, 14.0),  # V3: T down from H1, dead end
        (16.5, 18.0, 27.0, 27.0),  # R1: bounding region north-east, door to V1
        (16.0, 21.5, 16.5, 22.5),  # R1 door (1 m)
        (2.0, 2.0, 12.0, 13.5),  # R2: large room south-west, door to H1
        (9.0, 13.5, 10.5, 14.0),  # R2 door (1.5 m)
        (24.5, 4.0, 29.0, 10.0),  # R3: small room off V3
        (24.0, 6.0, 24.5, 7.0),  # R3 door (1 m)
    ]


def _paper_fig4_rects() -> list[Rect]:
    """62 x 41 m office: a corridor loop, 7 intersections, 3 dead ends, 14 rooms with doors."""
    corridors = [
        (8.0, 8.0, 62.0, 10.0),  # south corridor (loop)
        (8.0, 34.0, 62.0, 36.0),  # north corridor (loop)
        (8.0, 8.0, 10.0, 36.0),  # west corridor (loop)
        (60.0, 8.0, 62.0, 36.0),  # east corridor (loop)
        (34.0, 10.0, 36.0, 34.0),  # middle north-south corridor: T at both ends
        (10.0, 21.0, 50.0, 23.0),  # middle east-west corridor: T west, + middle, dead end east
        (8.0, 2.0, 10.0, 8.0),  # dead-end stub south of the south-west corner
        (62.0, 8.0, 70.0, 10.0),  # dead-end stub east of the south-east corner
        (60.0, 36.0, 62.0, 43.0),  # dead-end stub north of the north-east corner
    ]
    rooms = [
        # south of the south corridor, doors up into it
        (12.0, 2.5, 20.0, 7.5), (15.5, 7.5, 16.5, 8.0),
        (22.0, 2.5, 30.0, 7.5), (25.5, 7.5, 26.5, 8.0),
        (38.0, 2.5, 46.0, 7.5), (41.5, 7.5, 42.5, 8.0),
        (48.0, 2.5, 56.0, 7.5), (51.5, 7.5, 52.5, 8.0),
        # north of the north corridor, doors down into it
        (12.0, 36.5, 20.0, 42.0), (15.5, 36.0, 16.5, 36.5),
        (24.0, 36.5, 32.0, 42.0), (27.5, 36.0, 28.5, 36.5),
        (40.0, 36.5, 48.0, 42.0), (43.5, 36.0, 44.5, 36.5),
        # inside the loop
        (10.5, 10.5, 21.5, 20.5), (15.5, 10.0, 16.5, 10.5),  # door to the south corridor
        (22.5, 10.5, 33.5, 20.5), (33.5, 15.0, 34.0, 16.0),  # door to the middle corridor
        (10.5, 23.5, 33.5, 33.5), (27.5, 23.0, 28.5, 23.5),  # lab, door to the E-W corridor
        (36.5, 10.5, 59.5, 20.5), (59.5, 15.0, 60.0, 16.0),  # door to the east corridor
        (36.5, 23.5, 47.0, 33.5), (41.0, 33.5, 42.0, 34.0),  # door to the north corridor
        (48.0, 23.5, 59.5, 33.5), (59.5, 28.0, 60.0, 29.0),  # door to the east corridor
    ]
    return corridors + rooms


def _make(name: str, rects: list[Rect], start: Pose2D) -> World:
    return World(rectangles_to_segments(rects, _GRID_M), name=name, start_pose=start)


@functools.cache
def paper_fig3() -> World:
    """Hallways, intersections and bounding regions like the paper's Fig. 3b (~28 x 28 m)."""
    return _make("paper_fig3", _paper_fig3_rects(), Pose2D(3.0, 15.0, 0.0))


@functools.cache
def paper_fig4() -> World:
    """The exploration office of the paper's Fig. 4: corridor loop, intersections, rooms.

    The robot starts, facing east, in the mouth of the south-west corner (1.6 m east of its
    centre, where the distinctiveness measure peaks): "the robot begins at a starting node"
    (paper 8.2), so the start is a place worth an island and a loop closes onto it."""
    return _make("paper_fig4", _paper_fig4_rects(), Pose2D(10.6, 9.0, 0.0))


@functools.cache
def corridor() -> World:
    """A closed straight corridor 20 m x 2 m (tests)."""
    return _make("corridor", [(0.0, 0.0, 20.0, 2.0)], Pose2D(2.0, 1.0, 0.0))


@functools.cache
def square_room() -> World:
    """A closed 10 m x 10 m room (tests)."""
    return _make("square_room", [(0.0, 0.0, 10.0, 10.0)], Pose2D(5.0, 5.0, 0.0))


@functools.cache
def t_junction() -> World:
    """A T intersection of 2 m corridors: east-west 20 m, a 10 m branch north (tests)."""
    return _make(
        "t_junction",
        [(0.0, 0.0, 20.0, 2.0), (9.0, 2.0, 11.0, 12.0)],
        Pose2D(2.0, 1.0, 0.0),
    )


BUILTIN_WORLDS: dict[str, Callable[[], World]] = {
    "paper_fig3": paper_fig3,
    "paper_fig4": paper_fig4,
    "corridor": corridor,
    "square_room": square_room,
    "t_junction": t_junction,
}

# Free rectangles of each built-in, for tests and figures (e.g. sampling free space).
BUILTIN_FREE_RECTS: dict[str, Callable[[], list[Rect]]] = {
    "paper_fig3": _paper_fig3_rects,
    "paper_fig4": _paper_fig4_rects,
    "corridor": lambda: [(0.0, 0.0, 20.0, 2.0)],
    "square_room": lambda: [(0.0, 0.0, 10.0, 10.0)],
    "t_junction": lambda: [(0.0, 0.0, 20.0, 2.0), (9.0, 2.0, 11.0, 12.0)],
}


def builtin_world(name: str) -> World:
    """The built-in world called `name`; WorldError listing the names if there is none."""
    try:
        return BUILTIN_WORLDS[name]()
    except KeyError:
        raise WorldError(
            f"unknown built-in world {name!r} (known: {', '.join(sorted(BUILTIN_WORLDS))})"
        ) from None


def in_free_space(name: str, x_m: float, y_m: float, margin_m: float = 0.0) -> bool:
    """True when (x, y) [m] lies in a free rectangle of the built-in world, `margin_m` inside it.

    Conservative near junctions: the margin applies to each rectangle on its own.
    """
    for x0, y0, x1, y1 in BUILTIN_FREE_RECTS[name]():
        if x0 + margin_m <= x_m <= x1 - margin_m and y0 + margin_m <= y_m <= y1 - margin_m:
            return True
    return False

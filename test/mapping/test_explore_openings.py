"""Side openings as places (issue 16): the builder enters a doorway or a side hallway it passes
and attempts there; the island's exits (the hallway's continuation, a room's doorways only);
route following through doorways; turning back after an arrival that did not localize.

Public APIs only: `core.builder` (IslandBuilder, its configs, `opening`), `core.explore`,
`core.route`, and the offline harness `evaluation.explore_exits`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.builder import BuilderConfig
from island_mapping.core.builder.motion import StallWatch
from island_mapping.core.builder.opening import OpeningExit, OpeningRun, Openings
from island_mapping.core.builder.opening_config import OpeningConfig
from island_mapping.core.explore import ExitEvidence, find_exits
from island_mapping.core.explore.exits import (
    axis_widths,
    opening_exits,
    through_gates,
    wall_gap,
)
from island_mapping.core.explore.planner import nearest_unexplored
from island_mapping.core.graph import TopoGraph, reverse_strategy
from island_mapping.core.route import Drive, Sense, execute_strategy
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    Island,
    LineModel,
    ModelType,
    Pose2D,
)
from island_sim.core.robot import SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import world_from_dict

# A hallway along x (y 0..2) with a 1 m doorway (x 10..11) in its south wall into a 7 x 5 m room.
DOOR_WORLD = {"segments": [[0, 0, 10, 0], [11, 0, 22, 0], [0, 2, 22, 2], [0, 0, 0, 2],
                           [22, 0, 22, 2], [7, 0, 7, -5], [14, 0, 14, -5], [7, -5, 14, -5]],
              "start_pose": [2.0, 1.0, 0.0]}
# A room's walls in the frame of an island 1 m inside its doorway (theta 0 into the room): the
# doorway's wall behind (a 1 m gap at the origin's y), the far wall 4 m ahead, sides 3.5 m away.
ROOM = np.array([[-1, -3.5, -1, -0.5], [-1, 0.5, -1, 3.5], [4, -3.5, 4, 3.5],
                 [-1, 3.5, 4, 3.5], [-1, -3.5, 4, -3.5]], dtype=float)
HALL = np.array([[-6, -1, 6, -1], [-6, 1, 6, 1]], dtype=float)


def _headings(exits: tuple[Exit, ...] | list[Exit]) -> list[int]:
    """Exit headings [deg, 0..359] to the nearest 10 deg (an exit points into its opening's
    entry, a few degrees off the axis)."""
    return sorted(round(math.degrees(e.heading_rad) / 10.0) * 10 % 360 for e in exits)


def _room_evidence(arrival_rad: float | None = math.pi) -> ExitEvidence:
    return ExitEvidence(ROOM, np.zeros((0, 2)), np.array([[-3.0, 0.0, 0.0, 0.0]]),
                        arrival_rad)


def test_a_room_has_open_space_and_its_way_out_is_its_doorway() -> None:
    assert min(axis_widths(ROOM)) >= 3.0
    assert min(axis_widths(HALL)) == pytest.approx(2.0, abs=1e-9)
    ev = _room_evidence()
    found = find_exits(ev)
    assert len(found) > 1  # lanes into the room's interior are free for 3 m
    kept = through_gates(found, ev)
    assert _headings(kept) == [180]  # the doorway
    # A hallway is not open space: its exits stay.
    hall = ExitEvidence(HALL, np.zeros((0, 2)), np.array([[-3.0, 0.0, 0.0, 0.0]]), math.pi)
    assert through_gates(find_exits(hall), hall) == find_exits(hall)


def test_a_gap_between_collinear_walls_is_a_doorway_and_an_unseen_corner_is_not() -> None:
    from island_mapping.core.explore.config import ExitConfig

    model = LineModel(ROOM)
    assert wall_gap(model, math.pi, ExitConfig()) == pytest.approx(1.0)
    # toward a corner of the room where no wall was seen: a gap between perpendicular walls
    corner = LineModel(np.array([[4, -3.5, 4, 1.0], [0.5, 3.5, -1, 3.5]], dtype=float))
    assert wall_gap(corner, math.atan2(3.5, 4.0), ExitConfig()) is None


def test_an_island_in_a_doorway_keeps_its_arrival_and_gets_the_hallways_continuation() -> None:
    ev = _room_evidence()
    back = ControlStrategy.parse("Rot 180, Go 200, Rot 180")  # straight back out, turned in
    exits = opening_exits(find_exits(ev), ev, OpeningExit(side=-1, back=back, width_m=2.0,
                                                           narrow=True))
    plain = [e for e in exits if not e.is_side]
    side = [e for e in exits if e.is_side]
    assert _headings(plain) == [180]  # back out
    assert len(side) == 1
    cont = side[0]
    assert cont.prefix == back
    assert cont.side is ExitSide.LEFT  # it entered turning right: the hallway goes on left of in
    assert round(math.degrees(cont.heading_rad)) % 360 == 90
    assert [e.index for e in exits] == list(range(len(exits)))
    # A side hallway (no doorway crossed) keeps the exits leading on into it, not those back.
    branch = ExitEvidence(np.array([[-1.2, -1, 6, -1], [-1.2, 1, 6, 1]], dtype=float),
                          np.zeros((0, 2)), np.array([[-3.0, 0.0, 0.0, 0.0]]), math.pi)
    out = opening_exits(find_exits(branch), branch,
                        OpeningExit(1, ControlStrategy.parse("Rot 180, Go 120, Rot 180"), 2.0,
                                    narrow=False))
    assert set(_headings(tuple(e for e in out if not e.is_side))) == {0, 180}


def _feed(run: OpeningRun, cfg: OpeningConfig, steps: list[tuple[float, bool, bool]],
          theta: float = 0.0) -> float:
    """Feed (path length of the stretch [m], left open, right open) in 0.05 m scans."""
    s = 0.0
    for length, left, right in steps:
        for _ in range(round(length / 0.05)):
            s += 0.05
            run.update(s, left, right, theta, cfg)
    return s


def test_an_opening_in_a_hallway_is_offered_at_its_middle_once() -> None:
    cfg = OpeningConfig(enabled=True)
    run = OpeningRun()
    _feed(run, cfg, [(2.0, False, False), (0.8, False, True), (1.0, False, False)])
    got = run.take()
    assert got is not None
    centre, side = got
    assert centre == pytest.approx(2.0 + 0.4, abs=0.06)
    assert side == -1  # on the right
    assert run.take() is None  # offered once
    # In a room the sides come and go: no hallway before, no opening.
    room = OpeningRun()
    _feed(room, cfg, [(0.3, True, False), (0.2, False, False), (1.0, True, False),
                      (1.0, False, False)])
    assert room.take() is None
    # A turn of the follower ends the hallway: the run does not carry over.
    turned = OpeningRun()
    _feed(turned, cfg, [(2.0, False, False)])
    _feed(turned, cfg, [(0.5, True, False), (0.5, False, False)], theta=math.pi / 2)
    assert turned.take() is None


def test_an_opening_not_entered_soon_is_dropped() -> None:
    cfg = OpeningConfig(enabled=True, stale_m=3.0)
    ops = Openings(cfg)
    end = _feed(ops.run, cfg, [(2.0, False, False), (0.8, True, False), (0.5, False, False)])
    assert ops.pending(end)
    assert not ops.pending(end + 5.0)
    assert not Openings(OpeningConfig(enabled=False)).pending(0.0)


def test_a_stalled_drive_is_reported_once_after_its_time() -> None:
    watch = StallWatch(after_s=8.0)
    at = Pose2D(1.0, 2.0, 0.3)
    answers = [watch.update(0.1 * k, at, driving=True) for k in range(100)]
    assert answers.index(True) == 80 and sum(answers) == 1
    moving = StallWatch(after_s=8.0)
    assert not any(moving.update(0.1 * k, Pose2D(0.01 * k, 0.0, 0.0), True) for k in range(200))
    assert not any(StallWatch(8.0).update(0.1 * k, at, driving=False) for k in range(200))


def test_the_builder_enters_a_doorway_it_passes_and_builds_the_island_inside() -> None:
    world = world_from_dict(DOOR_WORLD)
    cfg = BuilderConfig(accept_on_legs=True, opening=OpeningConfig(enabled=True))
    run = explore_by_exits(SimSetup(world=world), 160.0, builder_cfg=cfg,
                           rng=np.random.default_rng(1))
    islands = [i for i in run.graph.islands() if i.id > 0]
    assert islands, "no island at the doorway"
    door = islands[0]
    assert door.origin_truth is not None
    o = door.origin_truth
    assert 7.0 < o.x < 14.0 and -5.0 < o.y < 0.0  # inside the room
    assert math.hypot(o.x - 10.5, o.y - 1.0) <= 2.5  # within reach of the hallway's junction
    cont = [e for e in door.exits if e.is_side]
    assert len(cont) == 1 and cont[0].side is ExitSide.LEFT and cont[0].prefix is not None
    # The continuation's way back out retraces the way in: it ends at the hallway's middle
    # before the doorway, facing it, where the robot stood before it turned in.
    edge = run.graph.get_edge(0, door.id)
    steps = [str(s) for s in edge.strategy.steps]
    turned = steps.index("Rot 90", 2)  # after the record and the drive back to the middle
    assert steps[turned + 1].startswith("Go ")
    way_in = ControlStrategy.parse(", ".join(steps[turned + 1:]))
    assert cont[0].prefix == reverse_strategy(way_in)
    assert run.collisions == 0


def test_route_following_drives_through_a_doorway() -> None:
    """`Go 400` from the hallway's middle, facing the doorway: through it into the room
    (before, the doorway's wall heard on the oblique transducers stopped it at the door)."""
    world = world_from_dict(DOOR_WORLD)
    rng = np.random.default_rng(2)
    robot = SimRobot(world, Pose2D(10.5, 1.0, -math.pi / 2), rng)
    sonar, near = SonarModel(SonarConfig()), NearbyRayCaster(world, 6.5)
    sense = Sense(0.0, robot.odom_pose, sonar.scan(near, robot.true_pose, rng), sonar.angles_rad)
    drive = Drive(sense)
    drive.deadline_s = 60.0
    for v, w in execute_strategy(drive, ControlStrategy.parse("Go 400")):
        blocked = False
        for _ in range(5):
            blocked |= robot.step(v, w, 0.02).blocked
        sense.t_s, sense.odom, sense.blocked = robot.time_s, robot.odom_pose, blocked
        sense.ranges_m = sonar.scan(near, robot.true_pose, rng)
    assert robot.true_pose.y < -2.0  # well into the room
    assert robot.collisions == 0


def test_the_planner_avoids_an_edge_whose_arrival_failed() -> None:
    g = TopoGraph()
    for i in range(3):
        g.put_island(Island(i, LineModel(np.zeros((0, 4))), ModelType.LINE, 1.0, 0.0,
                            exits=(Exit(0, 0.0, 1.0),) if i in (1, 2) else ()))
    g.put_edge(Edge(0, 1, ControlStrategy(()), 5.0, 5.0))
    g.put_edge(Edge(0, 2, ControlStrategy(()), 8.0, 8.0))
    assert nearest_unexplored(g, 0).island_id == 1
    t = nearest_unexplored(g, 0, penalty={frozenset((0, 1)): 100.0})
    assert t is not None and t.island_id == 2
    assert all(e.state is ExitState.UNEXPLORED for e in g.get_island(1).exits)


# A 2.6 x 2.6 m room (origin at its middle) whose 0.8 m doorway in the north wall opens on a
# hallway 0.9 m wide: no lane stays free for 3 m, the doorway's lane for 1.8 m.
SMALL_ROOM = np.array([[-1.3, -1.3, 1.3, -1.3], [1.3, -1.3, 1.3, 1.3], [-1.3, -1.3, -1.3, 1.3],
                       [-1.3, 1.3, -0.4, 1.3], [0.4, 1.3, 1.3, 1.3],
                       [-3.0, 2.2, 3.0, 2.2]], dtype=float)


def test_a_small_rooms_doorway_is_its_exit_though_no_lane_reaches_far() -> None:
    from island_mapping.core.explore.config import ExitConfig
    from island_mapping.core.explore.exits import island_exits

    ev = ExitEvidence(SMALL_ROOM, np.zeros((0, 2)), np.zeros((0, 4)))
    assert find_exits(ev) == ()  # every lane meets a wall within reach_m
    found = island_exits(ev)
    assert _headings(found) == [90]  # through the doorway
    assert island_exits(ev, ExitConfig(closed_reach_m=0.0)) == ()  # off
    # An island with a lane free for reach_m keeps only that: the fallback does not add lanes.
    hall = ExitEvidence(HALL, np.zeros((0, 2)), np.array([[-3.0, 0.0, 0.0, 0.0]]), math.pi)
    assert island_exits(hall) == through_gates(find_exits(hall), hall)

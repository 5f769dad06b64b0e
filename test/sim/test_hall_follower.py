"""Hall follower: centring, stopping short of walls, turn policies, strategy record, pausing."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pytest
from island_msgs_py.types import ControlStrategy, FloatArray, Pose2D, PrimitiveKind
from island_sim.core.hall_follower import (
    FollowerState,
    HallFollower,
    HallFollowerConfig,
    HallFollowerError,
    TurnChoice,
    TurnPolicy,
    parse_script,
)
from island_sim.core.robot import OdometryConfig, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World

DT_S = 0.02
STEPS_PER_SCAN = 5


def grid_world(rows: list[str], start: Pose2D, cell_m: float = 1.0) -> World:
    """Walls along the borders of '#' cells; rows[0] is the top (largest y) row."""
    free = np.array([[ch != "#" for ch in row] for row in rows])
    h, w = free.shape
    pad = np.zeros((h + 2, w + 2), dtype=bool)
    pad[1:-1, 1:-1] = free
    segs: list[list[float]] = []
    for i in range(h + 1):  # horizontal borders between padded rows i and i+1
        diff = pad[i, 1:-1] != pad[i + 1, 1:-1]
        y = (h - i) * cell_m
        j = 0
        while j < w:
            if diff[j]:
                k = j
                while k < w and diff[k]:
                    k += 1
                segs.append([j * cell_m, y, k * cell_m, y])
                j = k
            else:
                j += 1
    for j in range(w + 1):  # vertical borders between padded columns j and j+1
        diff = pad[1:-1, j] != pad[1:-1, j + 1]
        x = j * cell_m
        i = 0
        while i < h:
            if diff[i]:
                k = i
                while k < h and diff[k]:
                    k += 1
                segs.append([x, (h - k) * cell_m, x, (h - i) * cell_m])
                i = k
            else:
                i += 1
    return World(np.array(segs, dtype=np.float64), name="grid", start_pose=start)


def _ideal_hall_scan(x_m: float) -> tuple[FloatArray, FloatArray]:
    """(ranges, angles) of an ideal sonar at (x_m, 2.0) facing +x in a 2 m wide, 38 m long
    hall (grid cells of 1 m)."""
    rows = ["#" * 40, *(["#" + "." * 38 + "#"] * 2), "#" * 40]
    world = grid_world(rows, Pose2D(x_m, 2.0, 0.0))
    sonar = SonarModel(SonarConfig(ideal=True))
    return sonar.scan(world, world.start_pose), sonar.angles_rad


def loop_world() -> World:
    """A 26 x 16 m block with a 2 m corridor loop and a middle corridor (two T junctions)."""
    rows = []
    for i in range(16):
        row = ""
        for j in range(26):
            horiz = (1 <= i <= 2 or 13 <= i <= 14) and 1 <= j <= 24
            vert = (j in (1, 2, 12, 13, 23, 24)) and 1 <= i <= 14
            row += "." if horiz or vert else "#"
        rows.append(row)
    return grid_world(rows, Pose2D(5.0, 14.0, 0.0))


@dataclass
class Run:
    robot: SimRobot
    follower: HallFollower
    min_clearance_m: float
    true_path: np.ndarray


def simulate(
    world: World,
    follower: HallFollower,
    duration_s: float,
    seed: int = 1,
    odometry: OdometryConfig | None = None,
    ideal: bool = False,
    start: Pose2D | None = None,
) -> Run:
    rng = np.random.default_rng(seed)
    robot = SimRobot(world, start or world.start_pose, rng, odometry=odometry)
    sonar = SonarModel(SonarConfig(ideal=ideal))
    v = w = 0.0
    min_clear = math.inf
    path = []
    for k in range(round(duration_s / DT_S)):
        if k % STEPS_PER_SCAN == 0:
            ranges = sonar.scan(world, robot.true_pose, rng)
            v, w = follower.update(ranges, sonar.angles_rad, robot.odom_pose, robot.time_s)
            path.append(robot.true_pose.as_array())
        robot.step(v, w, DT_S)
        min_clear = min(min_clear, robot.clearance_m)
    return Run(robot, follower, min_clear, np.array(path))


def test_keeps_to_the_middle_of_a_hallway() -> None:
    rows = ["#" * 40, *(["#" + "." * 38 + "#"] * 2), "#" * 40]  # a 2 m wide, 38 m long hall
    world = grid_world(rows, Pose2D(2.0, 2.0 - 0.5, math.radians(12.0)))
    run = simulate(world, HallFollower(), 30.0)
    tail = run.true_path[-50:]  # the last 5 s
    assert np.max(np.abs(tail[:, 1] - 2.0)) < 0.12
    assert np.max(np.abs(tail[:, 2])) < math.radians(5.0)
    assert run.robot.collisions == 0
    assert run.robot.true_pose.x > 12.0  # made progress at about the cruise speed


def test_stops_short_of_a_dead_end_and_turns_back() -> None:
    rows = ["#" * 14, *(["#" + "." * 12 + "#"] * 2), "#" * 14]
    world = grid_world(rows, Pose2D(2.0, 2.0, 0.0))
    cfg = HallFollowerConfig()
    run = simulate(world, HallFollower(cfg), 40.0, odometry=OdometryConfig.exact())
    assert run.robot.collisions == 0
    assert run.min_clearance_m > cfg.stop_distance_m - cfg.robot_radius_m - 0.15
    xs = run.true_path[:, 0]
    assert xs.max() > 13.0 - cfg.stop_distance_m - 0.3  # got close to the end wall ...
    assert xs.max() < 13.0 - cfg.robot_radius_m  # ... without reaching it
    first = run.follower.decisions[0]
    assert first.at_dead_end and first.choice is TurnChoice.BACK
    rots = [s for s in run.follower.strategy().steps if s.kind is PrimitiveKind.ROT]
    assert rots and abs(rots[0].value - 180) <= 3


@pytest.mark.slow
def test_follows_the_loop_for_600_s_with_noise_and_drift() -> None:
    world = loop_world()
    follower = HallFollower(HallFollowerConfig(policy=TurnPolicy.RIGHT_HAND))
    run = simulate(world, follower, 600.0, seed=3)
    assert run.robot.collisions == 0
    assert run.min_clearance_m > 0.3
    decisions = follower.decisions
    assert len(decisions) >= 10
    # T junctions (two choices) were met, and decisions happened at distinct places
    assert sum(len(d.options) >= 2 for d in decisions) >= 3
    assert run.robot.distance_m > 200.0
    text = str(follower.strategy())
    parsed = ControlStrategy.parse(text)
    rots = [s.value for s in parsed.steps if s.kind is PrimitiveKind.ROT]
    assert len(rots) >= 10 and all(abs(r - 270) <= 5 for r in rots)  # right turns only
    assert parsed.length_m == pytest.approx(run.robot.distance_m, rel=0.05)


@pytest.mark.parametrize(
    ("policy", "expected"),
    [(TurnPolicy.LEFT_HAND, TurnChoice.STRAIGHT), (TurnPolicy.RIGHT_HAND, TurnChoice.RIGHT)],
)
def test_policy_decides_at_the_first_junction(policy: TurnPolicy, expected: TurnChoice) -> None:
    follower = HallFollower(HallFollowerConfig(policy=policy))
    run = simulate(loop_world(), follower, 25.0, odometry=OdometryConfig.exact())
    first = follower.decisions[0]
    assert set(first.options) == {TurnChoice.STRAIGHT, TurnChoice.RIGHT}
    assert first.choice is expected
    assert abs(first.odom_pose.x - 12.0) < 1.0  # the middle corridor's junction at x = 12-14 m
    assert run.robot.collisions == 0


def test_scripted_and_random_policies() -> None:
    scripted = HallFollower(HallFollowerConfig(policy=TurnPolicy.SCRIPTED, script="right, left"))
    simulate(loop_world(), scripted, 60.0, odometry=OdometryConfig.exact())
    assert [d.choice for d in scripted.decisions[:2]] == [TurnChoice.RIGHT, TurnChoice.LEFT]
    # at the second junction (bottom T, from the stem) left means heading east
    choices = []
    for _ in range(2):
        f = HallFollower(HallFollowerConfig(policy=TurnPolicy.RANDOM), np.random.default_rng(5))
        simulate(loop_world(), f, 80.0, odometry=OdometryConfig.exact())
        choices.append([d.choice for d in f.decisions])
    assert choices[0] == choices[1] and len(choices[0]) >= 2
    with pytest.raises(HallFollowerError, match="Generator"):
        HallFollower(HallFollowerConfig(policy=TurnPolicy.RANDOM))


def test_strategy_records_go_and_rot_in_table_1_units_and_resets() -> None:
    follower = HallFollower(HallFollowerConfig(policy=TurnPolicy.RIGHT_HAND))
    run = simulate(loop_world(), follower, 30.0, odometry=OdometryConfig.exact())
    steps = follower.strategy().steps
    assert steps[0].kind is PrimitiveKind.GO
    assert steps[1].kind is PrimitiveKind.ROT and abs(steps[1].value - 270) <= 3
    # the first Go is the straight run from x = 5 m to the junction's middle (x ~ 13 m)
    assert 700 <= steps[0].value <= 900
    total_cm = sum(s.value for s in steps if s.kind is PrimitiveKind.GO)
    assert total_cm == pytest.approx(run.robot.distance_m * 100.0, rel=0.02)
    follower.reset_strategy()
    assert str(follower.strategy()) == ""
    # keep going: the record restarts at the reset pose
    rng = np.random.default_rng(0)
    sonar = SonarModel(SonarConfig(ideal=True))
    world = loop_world()
    start_y = run.robot.odom_pose.y
    for k in range(200):
        if k % STEPS_PER_SCAN == 0:
            r = sonar.scan(world, run.robot.true_pose, rng)
            v, w = follower.update(r, sonar.angles_rad, run.robot.odom_pose, run.robot.time_s)
        run.robot.step(v, w, DT_S)
    after = follower.strategy()
    assert len(after.steps) == 1 and after.steps[0].kind is PrimitiveKind.GO
    assert after.length_m == pytest.approx(abs(run.robot.odom_pose.y - start_y), abs=0.1)


def test_pause_outputs_zero_and_resumes_cleanly() -> None:
    world = loop_world()
    sonar = SonarModel(SonarConfig(ideal=True))
    rng = np.random.default_rng(0)
    robot = SimRobot(world, world.start_pose, rng, odometry=OdometryConfig.exact())
    follower = HallFollower()
    v = w = 0.0
    for k in range(300):  # 6 s of following
        if k % STEPS_PER_SCAN == 0:
            r = sonar.scan(world, robot.true_pose, rng)
            v, w = follower.update(r, sonar.angles_rad, robot.odom_pose, robot.time_s)
        robot.step(v, w, DT_S)
    before = follower.strategy().length_m
    follower.set_enabled(False)
    assert follower.state is FollowerState.PAUSED
    for _ in range(100):  # someone else drives 1 m while the follower is paused
        r = sonar.scan(world, robot.true_pose, rng)
        assert follower.update(r, sonar.angles_rad, robot.odom_pose, robot.time_s) == (0.0, 0.0)
        robot.step(0.5, 0.0, DT_S)
    assert follower.strategy().length_m == pytest.approx(before, abs=0.01)
    follower.set_enabled(True)
    moved = []
    for k in range(200):
        if k % STEPS_PER_SCAN == 0:
            r = sonar.scan(world, robot.true_pose, rng)
            v, w = follower.update(r, sonar.angles_rad, robot.odom_pose, robot.time_s)
            moved.append(v)
        robot.step(v, w, DT_S)
    assert follower.state is FollowerState.FOLLOW and max(moved) > 0.3
    assert follower.strategy().length_m > before + 1.0


def test_a_door_is_not_taken_for_a_hallway() -> None:
    rows = [
        *(["#" * 12 + "....." + "#" * 13] * 3),  # a 5 x 3 m room ...
        "#" * 14 + "." + "#" * 15,  # ... behind a 1 m door on the left at x = 14-15 m
        *(["#" + "." * 28 + "#"] * 2),  # the 2 m hallway, y = 1-3 m
        "#" * 30,
    ]
    world = grid_world(rows, Pose2D(2.0, 2.0, 0.0))
    follower = HallFollower(HallFollowerConfig(policy=TurnPolicy.LEFT_HAND))
    run = simulate(world, follower, 40.0, odometry=OdometryConfig.exact())
    assert run.robot.collisions == 0
    assert run.robot.true_pose.x > 20.0  # went past the door
    # the door was seen as an opening and chosen (left hand), then recognised as too narrow
    assert follower.decisions[0].choice is TurnChoice.LEFT
    assert follower.cancelled_turns == 1
    assert np.max(run.true_path[:, 1]) < 3.0  # never entered the door


def test_bad_input_and_configuration_are_named() -> None:
    follower = HallFollower()
    with pytest.raises(HallFollowerError, match="ranges"):
        follower.update(np.ones(3), np.zeros(4), Pose2D(0, 0, 0), 0.0)
    with pytest.raises(HallFollowerError, match="t_s"):
        follower.update(np.ones(3), np.zeros(3), Pose2D(0, 0, 0), math.nan)
    with pytest.raises(HallFollowerError, match="stop_distance_m"):
        HallFollowerConfig(stop_distance_m=0.1)
    with pytest.raises(HallFollowerError, match="script"):
        HallFollowerConfig(script="left, sideways")
    with pytest.raises(HallFollowerError, match="policy"):
        HallFollowerConfig(policy="zigzag")  # type: ignore[arg-type]
    assert parse_script("l, s ,right;b") == (
        TurnChoice.LEFT, TurnChoice.STRAIGHT, TurnChoice.RIGHT, TurnChoice.BACK,
    )
    assert HallFollowerConfig(policy="random").policy is TurnPolicy.RANDOM  # type: ignore[arg-type]
    # NaN ranges count as no echo, not as an error
    v, w = follower.update(np.full(16, np.nan), np.linspace(0, 2 * np.pi, 16, endpoint=False),
                           Pose2D(0, 0, 0), 0.0)
    assert math.isfinite(v) and math.isfinite(w)


def test_paper_fig3_with_the_random_policy_touches_no_wall() -> None:
    from island_sim.core.world_loader import load_world

    follower = HallFollower(HallFollowerConfig(policy=TurnPolicy.RANDOM), np.random.default_rng(4))
    run = simulate(load_world("paper_fig3"), follower, 200.0, seed=4)
    assert run.robot.collisions == 0
    assert run.min_clearance_m > 0.1
    turns = [s for s in follower.strategy().steps if s.kind is PrimitiveKind.ROT]
    assert len(turns) >= 4
    assert run.robot.distance_m > 60.0


def test_reset_in_the_middle_of_a_turn_keeps_only_the_rest_of_it() -> None:
    world = loop_world()
    sonar = SonarModel(SonarConfig(ideal=True))
    rng = np.random.default_rng(0)
    robot = SimRobot(world, world.start_pose, rng, odometry=OdometryConfig.exact())
    follower = HallFollower(HallFollowerConfig(policy=TurnPolicy.RIGHT_HAND))
    v = w = 0.0
    reset_at: float | None = None
    turn_start: float | None = None
    for k in range(2000):
        if k % STEPS_PER_SCAN == 0:
            r = sonar.scan(world, robot.true_pose, rng)
            v, w = follower.update(r, sonar.angles_rad, robot.odom_pose, robot.time_s)
            if turn_start is None and follower.state is FollowerState.TURN and abs(w) > 0.5:
                turn_start = robot.odom_pose.theta
            turned = turn_start is not None and abs(robot.odom_pose.theta - turn_start) > 0.5
            if reset_at is None and turned:
                follower.reset_strategy()
                reset_at = robot.odom_pose.theta
                assert str(follower.strategy()) == ""
            if reset_at is not None and follower.state is FollowerState.FOLLOW:
                break
        robot.step(v, w, DT_S)
    assert reset_at is not None
    steps = follower.strategy().steps
    assert steps[0].kind is PrimitiveKind.ROT
    rest_deg = math.degrees(abs(robot.odom_pose.theta - reset_at))
    assert 360 - steps[0].value == pytest.approx(rest_deg, abs=3.0)  # a right turn: CW
    assert 10 < rest_deg < 65  # only what remained of the quarter turn


def test_no_progress_while_driving_counts_as_blocked() -> None:
    """A wall the sonar cannot see (e.g. a specular glass pane) stops the wheels: odometry tells.
    With backing off disabled the follower decides where it stands, as at a wall ahead."""
    ranges, angles = _ideal_hall_scan(5.0)
    cfg = HallFollowerConfig(stall_time_s=1.0, backoff_m=0.0)
    follower = HallFollower(cfg)
    stuck = Pose2D(5.0, 2.0, 0.0)
    commands = []
    for k in range(30):  # 3 s at 10 Hz: the sonar sees a free hall, the odometry never moves
        commands.append(follower.update(ranges, angles, stuck, 0.1 * k))
        if follower.stalls:
            break
    assert follower.stalls == 1
    assert 0.1 * len(commands) == pytest.approx(cfg.stall_time_s + 0.2, abs=0.25)
    assert max(v for v, _ in commands[:-1]) > 0.3  # it did try to drive
    last = follower.decisions[-1]
    assert last.at_dead_end and last.choice is TurnChoice.BACK
    assert follower.state is FollowerState.TURN


def _drive_into_pane(follower: HallFollower, ranges: object, angles: object,
                     pane_x_m: float) -> list[tuple[float, float]]:
    """Odometry integrates the commands along x, except that it cannot pass `pane_x_m` (an
    unseen wall); 20 s at 10 Hz. The commands given."""
    x, commands = 5.0, []
    for k in range(200):
        v, w = follower.update(ranges, angles, Pose2D(x, 2.0, 0.0), 0.1 * k)
        commands.append((v, w))
        x = min(x + 0.1 * v, pane_x_m)
        if follower.state is FollowerState.TURN:
            break
    return commands


def test_a_stall_backs_off_before_deciding() -> None:
    """Stalled at an unseen wall, the robot backs straight away by backoff_m (a disk touching
    a jamb can always leave the way it came), then decides as at a wall ahead; the backing is
    taken off the Go it interrupted."""
    ranges, angles = _ideal_hall_scan(5.0)
    cfg = HallFollowerConfig(stall_time_s=1.0, backoff_m=0.3, backoff_speed_mps=0.15)
    follower = HallFollower(cfg)
    commands = _drive_into_pane(follower, ranges, angles, pane_x_m=6.0)
    assert follower.stalls == 1
    backing = [v for v, _ in commands if v < 0.0]
    assert backing and all(v == pytest.approx(-0.15) for v in backing)
    assert 0.1 * 0.15 * len(backing) == pytest.approx(0.3, abs=0.03)  # backoff_m of travel
    last = follower.decisions[-1]
    assert last.at_dead_end and last.choice is TurnChoice.BACK
    go = follower.strategy().steps[0]
    assert go.kind is PrimitiveKind.GO and go.value == pytest.approx(70, abs=4)  # 1.0 - 0.3 m


def test_backing_off_stops_at_a_wall_behind() -> None:
    """A wall close behind ends the backing at once: the follower decides where it stands."""
    ranges, angles = _ideal_hall_scan(1.45)  # the hall's end wall 0.45 m behind
    follower = HallFollower(HallFollowerConfig(stall_time_s=1.0, backoff_m=0.3))
    follower.update(ranges, angles, Pose2D(5.0, 2.0, 0.0), 0.0)
    commands = _drive_into_pane(follower, ranges, angles, pane_x_m=5.0)
    assert follower.stalls == 1
    assert not any(v < 0.0 for v, _ in commands)
    assert follower.decisions[-1].at_dead_end


def test_a_pause_is_not_time_spent_stuck() -> None:
    """Paused just after the wheels stopped (a controller took over), then resumed much later:
    the pause does not count towards `stall_time_s`, so the follower does not see itself
    blocked at once and turn back."""
    ranges, angles = _ideal_hall_scan(5.0)
    cfg = HallFollowerConfig(stall_time_s=1.0)
    follower = HallFollower(cfg)
    stuck = Pose2D(5.0, 2.0, 0.0)
    for k in range(6):  # 0.5 s of driving without progress: not yet a stall
        follower.update(ranges, angles, stuck, 0.1 * k)
    assert follower.stalls == 0
    follower.set_enabled(False)
    assert follower.update(ranges, angles, stuck, 30.0) == (0.0, 0.0)
    follower.set_enabled(True)
    v, _ = follower.update(ranges, angles, stuck, 60.0)  # resumed 60 s later, still in place
    assert follower.stalls == 0
    assert v > 0.0 and follower.state is FollowerState.FOLLOW
    for k in range(1, 30):  # stuck for real after the resume: a stall, after stall_time_s
        follower.update(ranges, angles, stuck, 60.0 + 0.1 * k)
        if follower.stalls:
            break
    assert follower.stalls == 1 and 0.1 * k == pytest.approx(cfg.stall_time_s + 0.1, abs=0.25)


def test_backing_speed_set_to_zero_while_backing_ends_the_backing() -> None:
    """A live reconfigure to backoff_speed_mps 0 mid-backing: no division by zero, the
    follower stops backing and decides as at a wall."""
    ranges, angles = _ideal_hall_scan(5.0)
    cfg = HallFollowerConfig(stall_time_s=1.0)
    follower = HallFollower(cfg)
    stuck = Pose2D(5.0, 2.0, 0.0)
    k = 0
    while follower.state is not FollowerState.BACK_OFF and k < 50:
        follower.update(ranges, angles, stuck, 0.1 * k)
        k += 1
    assert follower.state is FollowerState.BACK_OFF
    follower.reconfigure(dataclasses.replace(cfg, backoff_speed_mps=0.0))
    assert follower.update(ranges, angles, stuck, 0.1 * k) == (0.0, 0.0)
    assert follower.state is not FollowerState.BACK_OFF

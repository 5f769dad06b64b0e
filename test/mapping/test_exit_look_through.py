"""Exits along an island axis the star sees straight down (ExitConfig.look_through, issue 16).

A sonar reports the nearest echo anywhere in its 25-deg cone as if on its axis: in a 2 m hallway
with a door on each side 1-3 m ahead, the readings whose cones take in a door jamb's face put
echoes, and model lines, across the hallway, and the exit finder saw no way on (office 11
seed 3 ended by itself after 95 s with 2 of 60 places). The readings along the hallway itself
see past it; a wall across the hallway echoes in every one of them.

Public APIs only: the simulated sonar, the line fitter, `find_exits`, the offline explorer.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.explore import (
    ExitConfig,
    ExitEvidence,
    ExploreError,
    ExplorerConfig,
    find_exits,
)
from island_mapping.core.lines import fit_lines
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_msgs_py.types import Exit, Pose2D
from island_sim.core.sonar import SonarModel
from island_sim.core.world import World

# A hallway along +x (y in [-1, 1]); a door 1 m wide in each wall, left at x 1.0-2.0 and right
# at x 1.75-2.75, through 0.5 m thick walls into a room on each side [m].
HALLWAY = [[-4, 1, 1.0, 1], [2.0, 1, 12, 1], [-4, -1, 1.75, -1], [2.75, -1, 12, -1],
           [1.0, 1, 1.0, 1.5], [2.0, 1, 2.0, 1.5], [1.0, 1.5, -2, 1.5], [2.0, 1.5, 6, 1.5],
           [1.75, -1, 1.75, -1.5], [2.75, -1, 2.75, -1.5], [1.75, -1.5, -2, -1.5],
           [2.75, -1.5, 6, -1.5], [-2, 1.5, -2, 5], [-2, 5, 6, 5], [6, 5, 6, 1.5],
           [-2, -1.5, -2, -5], [-2, -5, 6, -5], [6, -5, 6, -1.5], [-4, -1, -4, 1],
           [12, -1, 12, 1]]
STAR_XS_M = (-1.2, -0.6, 0.0)  # where the star turned, along the hallway [m]


def hallway(closed_at_m: float | None = None) -> World:
    walls = list(HALLWAY)
    if closed_at_m is not None:  # a wall across the hallway
        walls.append([closed_at_m, -1, closed_at_m, 1])
    return World(np.array(walls, dtype=float), start_pose=Pose2D(0.0, 0.0, 0.0))


def star_evidence(world: World, seed: int) -> ExitEvidence:
    """What a star at the origin (heading 0) gives the exit finder: turning in place at
    STAR_XS_M, a scan every 5 deg."""
    sonar, rng = SonarModel(seed=seed), np.random.default_rng(seed)
    turns = np.radians(np.arange(0.0, 360.0, 5.0))
    poses = np.array([[x, 0.0, th] for x in STAR_XS_M for th in turns])
    ranges = sonar.scan_many(world, poses, rng)
    bearings = poses[:, 2:3] + sonar.angles_rad[None, :]
    at = np.repeat(poses[:, :2], ranges.shape[1], axis=0)
    looks = np.column_stack([at, bearings.ravel(), ranges.ravel()])
    echo = np.isfinite(looks[:, 3])
    pts = at[echo] + looks[echo, 3:4] * np.column_stack(
        [np.cos(looks[echo, 2]), np.sin(looks[echo, 2])])
    driven = np.array([[min(STAR_XS_M), 0.0, max(STAR_XS_M), 0.0]])
    return ExitEvidence(fit_lines(pts).segments, pts, driven, None, looks)


def ahead(exits: tuple[Exit, ...], within_deg: float = 10.0) -> bool:
    return any(abs(math.degrees(e.heading_rad)) <= within_deg for e in exits)


@pytest.mark.parametrize("seed", [1, 2])
def test_the_hallway_past_two_doors_is_an_exit(seed: int) -> None:
    ev = star_evidence(hallway(), seed)
    assert not ahead(find_exits(ev, ExitConfig(look_through=False)))  # the jambs close it
    assert ahead(find_exits(ev))


@pytest.mark.parametrize("closed_at_m", [2.6, 3.0])
def test_a_wall_across_the_hallway_stays_closed(closed_at_m: float) -> None:
    """Readings from behind the origin see the wall beyond reach_m; what counts is how far
    ahead of the origin they see."""
    ev = star_evidence(hallway(closed_at_m), seed=1)
    assert not ahead(find_exits(ev))


def test_without_readings_the_model_decides() -> None:
    ev = star_evidence(hallway(), seed=1)
    bare = ExitEvidence(ev.segments, ev.points, ev.driven, None)
    assert find_exits(bare) == find_exits(ev, ExitConfig(look_through=False))


def test_the_builder_hands_the_star_readings_to_the_exit_finder() -> None:
    """Offline exploration in the hallway world (seed 3): island 0's exit down the hallway is
    there with look_through, and missing without it."""
    found = []
    for look in (True, False):
        cfg = ExplorerConfig(exit=ExitConfig(look_through=look))
        run = explore_by_exits(SimSetup(world=hallway()), 40.0, explorer_cfg=cfg,
                               rng=np.random.default_rng(3))
        found.append(ahead(run.graph.islands()[0].exits))
    assert found == [True, False]


@pytest.mark.parametrize(("looks", "what"), [
    (np.array([[0.0, 0.0, 0.0, -1.0]]), "ranges must be > 0"),
    (np.array([[0.0, 0.0, 0.0, np.nan]]), "ranges must be > 0"),
    (np.array([[np.nan, 0.0, 0.0, 1.0]]), "looks"),
    (np.zeros((2, 3)), "looks"),
])
def test_bad_readings_are_refused_by_name(looks: np.ndarray, what: str) -> None:
    with pytest.raises(ExploreError, match=what):
        ExitEvidence(np.zeros((0, 4)), np.zeros((0, 2)), np.zeros((0, 4)), None, looks)


@pytest.mark.parametrize("bad", [{"look_min_readings": 0}, {"look_min_fraction": 1.5},
                                 {"look_deg": -1.0}])
def test_bad_look_settings_are_refused_by_name(bad: dict[str, float]) -> None:
    with pytest.raises(ExploreError, match=next(iter(bad))):
        ExitConfig(**bad)  # type: ignore[arg-type]

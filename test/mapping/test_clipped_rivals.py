"""A recognition from a search window cut to the caps is refused when another island, anywhere,
fits the points as well near its own origin (issue 16: a false loop closure must be rarer than
a missed one).

Traced on paper_fig4 seed 3 (7200 s): after a lost wander the robot stood at island 0's place
with a 10.7 m position sigma; the star's points fitted island 3, 24.8 m away (inliers 1.0,
Mahalanobis 9.0), and island 0, its odometric estimate drifted 23.6 m off, lay outside both the
clipped window and the 12 m rival window. The docking made 6 false arrivals.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from island_mapping.core.builder import BuilderConfig
from island_mapping.core.builder.diagnostics import Diagnostics, Refusal
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition, Recognizer
from island_mapping.core.explore import ExplorerConfig
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

# A T junction: the corridor along x, a branch north [m].
TEE = np.array([[-6, -1, 6, -1], [-6, 1, -1, 1], [1, 1, 6, 1], [-1, 1, -1, 6],
                [1, 1, 1, 6]], dtype=float)
# A corner: the corridor from the west turns north [m].
CORNER = np.array([[-6, -1, 1, -1], [1, -1, 1, 6], [-6, 1, -1, 1], [-1, 1, -1, 6]],
                  dtype=float)
ROBOT = Pose2D(0.3, -0.2, 0.0)  # the robot in the true island's frame, and in odometry


def _points(rng: np.random.Generator) -> np.ndarray:
    """Echoes of the T within 5 m of ROBOT, in its frame [m]."""
    pts = []
    for x0, y0, x1, y1 in TEE:
        t = np.linspace(0.0, 1.0, max(2, int(math.hypot(x1 - x0, y1 - y0) / 0.2)))[:, None]
        pts.append(np.hstack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)]))
    p = np.concatenate(pts)
    p = p + rng.normal(0.0, 0.02, p.shape)
    p = p[np.hypot(p[:, 0] - ROBOT.x, p[:, 1] - ROBOT.y) <= 5.0]
    return p - np.array([ROBOT.x, ROBOT.y])


def _recognize(true_place: np.ndarray, clipped_rivals: bool
               ) -> tuple[Recognition | None, Diagnostics]:
    """The robot stands at island 0's place (model `true_place`), whose origin odometry has
    drifted to 30 m away; island 1, a T, is where odometry says the robot is. The position
    sigma is 10 m: the star's 2.5-sigma window is cut to its 10 m cap."""
    revisit = dataclasses.replace(ExplorerConfig().revisit, clipped_rivals=clipped_rivals)
    diag = Diagnostics()
    rec = Recognizer(BuilderConfig(revisit=revisit), diag)
    rec.remember(0, Pose2D(-30.0, 4.0, 0.0), np.zeros((3, 3)))
    rec.remember(1, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
    snap = PoseSnapshot(ROBOT, np.diag([100.0, 100.0, math.radians(10.0) ** 2]), 3.0,
                        math.radians(10.0), None, 60.0)
    islands = [Island(0, LineModel(true_place), ModelType.LINE, 1.0, 0.0),
               Island(1, LineModel(TEE), ModelType.LINE, 1.0, 0.0)]
    return rec.recognize(_points(np.random.default_rng(3)), ROBOT, snap, islands,
                         star=True), diag


def test_the_explorer_checks_clipped_windows() -> None:
    assert ExplorerConfig().revisit.clipped_rivals
    assert not BuilderConfig().revisit.clipped_rivals


def test_a_look_alike_outside_every_window_refuses_the_recognition() -> None:
    """Without the check the T where odometry says the robot is would be docked onto (the
    false merge of the trace); with it, island 0's own T fitting at its origin refuses it."""
    wrong, _ = _recognize(TEE, clipped_rivals=False)
    assert wrong is not None and wrong.island_id == 1
    found, diag = _recognize(TEE, clipped_rivals=True)
    assert found is None
    assert diag.revisit_refusals.get(Refusal.FAR_LOOK_ALIKE.value, 0) == 1


def test_a_place_like_no_other_is_still_recognised() -> None:
    """Island 0 a corner: nothing else fits the T's points, the recognition is kept."""
    found, diag = _recognize(CORNER, clipped_rivals=True)
    assert found is not None and found.island_id == 1
    assert math.hypot(found.pose.x - ROBOT.x, found.pose.y - ROBOT.y) < 0.15
    assert Refusal.FAR_LOOK_ALIKE.value not in diag.revisit_refusals

"""Turns that cancel: a star's legs and a look's circle turn the way that undoes the robot's
net turning (`StarConfig.unwind_turns`, `NavigateConfig.unwind_turns`).

A wheelbase error scales every odometric turn by the same fraction, so the heading error it
leaves grows with the net turn, not with the turning done: stars and looks that always turn
left drove it to 90 deg and more in an hour (docs/exploration.md, session 23). The T world
explored offline (simulator, builder, explorer, follower) both ways, through the public
harness `explore_by_exits`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from island_mapping.core.builder import BuilderConfig
from island_mapping.core.route import NavigateConfig
from island_mapping.evaluation.explore_exits import ExitsRun, explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_msgs_py.geometry import wrap_angles
from island_sim.core.world_loader import load_world


def _turns_deg(run: ExitsRun) -> tuple[float, float]:
    """(net turn, turning done) of the true path [deg]."""
    d = wrap_angles(np.diff(run.truth_path[:, 2]))
    return math.degrees(float(d.sum())), math.degrees(float(np.abs(d).sum()))


def _explore(unwind: bool) -> ExitsRun:
    b = BuilderConfig()
    b = dataclasses.replace(b, star=dataclasses.replace(b.star, unwind_turns=unwind))
    return explore_by_exits(SimSetup(world=load_world("t_junction")), 600.0, builder_cfg=b,
                            nav=NavigateConfig(unwind_turns=unwind),
                            rng=np.random.default_rng(1))


def test_stars_and_looks_unwind_the_net_turn() -> None:
    unwound, left = _explore(True), _explore(False)
    for run in (unwound, left):
        assert run.done and run.collisions == 0 and run.false_arrivals == 0
    net, done = _turns_deg(unwound)
    assert done > 1800.0  # five stars and looks at the least
    assert abs(net) < 0.25 * done
    net_left, done_left = _turns_deg(left)
    assert net_left > 0.75 * done_left
